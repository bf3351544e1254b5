//! The paper's occlusion bins (§VI-A-2) over a sample's occlusion level ([`crate::OcclusionInfo`]):
//! below 80 %, 80 % to 85 % inclusive, above 85 % (FORMAT.md, "Occlusion bins").

/// One bin of the occlusion level. Its position in [`OcclusionBin::ALL`] is its index in the
/// format's histograms (a shard's `occlusion_histogram`, the manifest's `occlusion.counts`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum OcclusionBin {
    Below80,
    From80To85,
    Above85,
}

impl OcclusionBin {
    pub const ALL: [OcclusionBin; 3] = [OcclusionBin::Below80, OcclusionBin::From80To85, OcclusionBin::Above85];

    /// The levels between the bins: below the first is [`OcclusionBin::Below80`], up to and
    /// including the second [`OcclusionBin::From80To85`], above it [`OcclusionBin::Above85`].
    pub const BOUNDS: [f64; 2] = [0.80, 0.85];

    /// The bin of an occlusion level in [0, 1]; `None` for NaN (no level).
    pub fn of(level: f64) -> Option<OcclusionBin> {
        Self::between(level, Self::BOUNDS)
    }

    /// [`OcclusionBin::of`] for a level held as `f32`, compared with the bounds in `f32` too: a
    /// level of exactly 0.85 stays in the middle bin (0.85 rounded to `f32` is above 0.85).
    pub fn of_f32(level: f32) -> Option<OcclusionBin> {
        Self::between(level, Self::BOUNDS.map(|b| b as f32))
    }

    fn between<T: PartialOrd>(level: T, [low, high]: [T; 2]) -> Option<OcclusionBin> {
        level.partial_cmp(&low)?; // NaN
        Some(if level < low {
            OcclusionBin::Below80
        } else if level <= high {
            OcclusionBin::From80To85
        } else {
            OcclusionBin::Above85
        })
    }

    /// The bin's index in the format's histograms.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The bin's name in the data files (the manifest's `occlusion.bins`) and in `vtgen`'s
    /// tables: `<80%`, `80-85%`, `>85%`.
    pub fn key(self) -> &'static str {
        match self {
            OcclusionBin::Below80 => "<80%",
            OcclusionBin::From80To85 => "80-85%",
            OcclusionBin::Above85 => ">85%",
        }
    }

    /// The bin's name in reports: `< 80 %`, `80–85 %`, `> 85 %`.
    pub fn label(self) -> &'static str {
        match self {
            OcclusionBin::Below80 => "< 80 %",
            OcclusionBin::From80To85 => "80–85 %",
            OcclusionBin::Above85 => "> 85 %",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_bounds_and_indices() {
        let of = |l: f64| OcclusionBin::of(l).map(OcclusionBin::index);
        assert_eq!([0.0, 0.7999, 0.80, 0.85, 0.8501, 1.0].map(of), [0, 0, 1, 1, 2, 2].map(Some));
        assert_eq!(OcclusionBin::of(f64::NAN), None);
        assert_eq!(OcclusionBin::of_f32(0.5), Some(OcclusionBin::Below80));
        assert_eq!(OcclusionBin::of_f32(0.8), Some(OcclusionBin::From80To85));
        // A level of 0.85 read as f32 is still in the middle bin, as in f64.
        assert_eq!(OcclusionBin::of_f32(0.85), Some(OcclusionBin::From80To85));
        assert_eq!(OcclusionBin::of(0.85f32 as f64), Some(OcclusionBin::Above85), "why of_f32 exists");
        assert_eq!(OcclusionBin::of_f32(0.9), Some(OcclusionBin::Above85));
        assert_eq!(OcclusionBin::of_f32(f32::NAN), None);
        assert!(OcclusionBin::ALL.iter().enumerate().all(|(i, b)| b.index() == i));
    }
}
