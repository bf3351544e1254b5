//! Measuring a transform: area-weighted surface samples of the mesh, moved by it, and each one's
//! exact distance to the closest point of the unmoved surface.

use glam::{DMat3, DMat4, DVec3};

use super::closest::Bvh;
use super::linalg::outer;
use crate::mesh::diameter_of;
use crate::surface::SurfaceSampler;

/// Surface samples used to measure a transform ("a few thousand", area-weighted).
pub const SURFACE_SAMPLES: usize = 4000;
/// Seed of the surface samples (SplitMix64).
pub const SAMPLE_SEED: u64 = 0x7667_656e_5f73_796d;

/// The tolerance of a symmetry: max(1 mm, 1% of the diameter). A transform is a symmetry when it
/// moves 95% of the surface by at most the tolerance and 99% by at most twice it
/// ([`Displacement::passes`]).
///
/// Why the 95th percentile, and not the maximum or the 99th alone: the real scans are not exact
/// boxes or cylinders, and their worst points are where the physical object is bent, not where the
/// shape has another symmetry. Measured on the 11 google_16k scans (4000 samples, the frame the
/// search finds; p95 / p99 / max in mm, the tolerance in brackets):
///
/// | scan | transform | p95 | p99 | max | |
/// |---|---|---|---|---|---|
/// | gelatin box [1.14] | flips x, y, z | 0.89–0.94 | 1.37–1.47 | 1.79–2.02 | kept: its lid bulges ~1.5 mm |
/// | sugar box [1.99] | flip z | 1.11 | 1.52 | 2.35 | kept |
/// | sugar box | flips x, y | 3.15, 3.28 | 3.53, 3.92 | 3.70, 4.15 | dropped: 45 mm thick at the base, 39 mm at the top |
/// | potted meat can [1.29] | flip z | 0.41 | 1.47 | 2.64 | kept |
/// | potted meat can | flips x, y (lid ↔ base) | 2.61, 2.62 | 4.18, 4.14 | 5.71, 5.77 | dropped |
/// | cracker box [2.70] | flips x, y, z | 4.01–5.20 | 5.09–6.19 | 5.48–6.63 | dropped: a 6–7 mm dent in a large face |
/// | tomato soup can [1.21] | turns by 30°…330° (worst) | 2.50 | 3.82 | 4.80 | dropped: the wall is out of round by up to 2.8 mm (circle fits per height: centres within 0.2 mm of the axis, residual RMS 0.3–0.9 mm) |
///
/// Under the maximum, or the 99th percentile alone, the gelatin box would lose all three flips to
/// the 1.5 mm bulge of its lid, although they are 12 times better than the axis-aligned flips (p95
/// 11 mm, p99 14 mm). The 95th percentile alone would let a twentieth of the surface move
/// arbitrarily far: the procedural mug's best flip about its body axis has p95 0.02 mm and p99
/// 22 mm (the handle), and is caught only by the 99th percentile at twice the tolerance. The
/// procedural stand-ins' symmetries are exact (< 0.001 mm), and every wrong transform measured fails
/// by far: the axis-aligned flips of a box turned 13° (p95 12.8 mm), a quarter turn of a 60 × 100 mm
/// box, a box or a mug as a body of revolution.
pub fn tolerance(diameter: f64) -> f64 {
    (0.01 * diameter).max(0.001)
}

/// How far a transform moves the surface off itself, metres: statistics over the surface samples of
/// the distance from the moved sample to the closest point of the (unmoved) surface.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Displacement {
    pub max: f64,
    pub p99: f64,
    pub p95: f64,
}

impl Displacement {
    /// Whether the transform is a symmetry within `tolerance`: p95 ≤ tolerance and p99 ≤ 2 ×
    /// tolerance (see [`tolerance`]).
    pub fn passes(&self, tolerance: f64) -> bool {
        self.p95 <= tolerance && self.p99 <= 2.0 * tolerance
    }

    /// The worse of two, statistic by statistic (for a family of transforms).
    pub fn worst(self, other: Displacement) -> Displacement {
        Displacement { max: self.max.max(other.max), p99: self.p99.max(other.p99), p95: self.p95.max(other.p95) }
    }

    fn from_distances(mut d: Vec<f64>) -> Displacement {
        if d.is_empty() {
            return Displacement::default();
        }
        d.sort_by(f64::total_cmp);
        // Nearest-rank percentiles.
        let rank = |q: f64| d[((q * d.len() as f64).ceil() as usize).clamp(1, d.len()) - 1];
        Displacement { max: d[d.len() - 1], p99: rank(0.99), p95: rank(0.95) }
    }
}

/// Measures transforms of one mesh: its surface samples and exact closest-point distances.
pub struct SymmetryChecker {
    pub(super) surface: Bvh,
    pub(super) samples: Vec<DVec3>,
    pub(super) diameter: f64,
    /// Area-weighted centroid and covariance of the surface.
    pub(super) centroid: DVec3,
    pub(super) covariance: DMat3,
    pub(super) vertices: Vec<DVec3>,
}

impl SymmetryChecker {
    /// [`SURFACE_SAMPLES`] samples with [`SAMPLE_SEED`].
    pub fn new(positions: &[[f32; 3]], indices: &[u32]) -> Self {
        Self::with_samples(positions, indices, SURFACE_SAMPLES, SAMPLE_SEED)
    }

    pub fn with_samples(positions: &[[f32; 3]], indices: &[u32], samples: usize, seed: u64) -> Self {
        let vertices: Vec<DVec3> = positions.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
        let tris: Vec<[DVec3; 3]> = indices
            .chunks_exact(3)
            .filter_map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| vertices.get(i as usize).copied());
                Some([a?, b?, c?])
            })
            // Zero-area triangles add no surface (their points lie on their neighbours' edges).
            .filter(|[a, b, c]| (*b - *a).cross(*c - *a).length_squared() > 0.0)
            .collect();
        let sampler = SurfaceSampler::new(tris);
        // Area, centroid and second moment (exact over each triangle).
        let area = sampler.total_area();
        let mut first = DVec3::ZERO;
        let mut second = DMat3::ZERO;
        for ([a, b, c], &ar) in sampler.triangles().iter().zip(sampler.areas()) {
            let s = *a + *b + *c;
            first += ar / 3.0 * s;
            second += (outer(*a, *a) + outer(*b, *b) + outer(*c, *c) + outer(s, s)) * (ar / 12.0);
        }
        let (centroid, covariance) = if area > 0.0 {
            let c = first / area;
            (c, second * (1.0 / area) - outer(c, c))
        } else {
            (DVec3::ZERO, DMat3::ZERO)
        };
        // Area-weighted samples: a triangle by its running area, a point in it by the square-root
        // mapping. The search's `<=` and that mapping are this checker's since its first
        // `models_info.json`: the other samplers' `<` and folded pair would move every sample,
        // and the derived symmetries' last bits with them.
        let mut rng = SplitMix64(seed);
        let mut pts = Vec::with_capacity(samples);
        if area > 0.0 {
            for _ in 0..samples {
                let u = rng.next_f64() * area;
                let k = sampler.pick_by(|&c| c <= u);
                let (r1, r2) = (rng.next_f64(), rng.next_f64());
                pts.push(sampler.point_sqrt(k, r1, r2));
            }
        }
        let surface = Bvh::new(sampler.triangles().to_vec());
        SymmetryChecker { surface, samples: pts, diameter: diameter_of(positions), centroid, covariance, vertices }
    }

    pub fn diameter(&self) -> f64 {
        self.diameter
    }

    /// max(1 mm, 1% of the diameter).
    pub fn tolerance(&self) -> f64 {
        tolerance(self.diameter)
    }

    /// The surface samples (model frame, metres).
    pub fn samples(&self) -> &[DVec3] {
        &self.samples
    }

    /// Exact distance from `p` to the closest point of the mesh surface.
    pub fn distance(&self, p: DVec3) -> f64 {
        self.surface.distance_sq(p, &mut Vec::new()).sqrt()
    }

    /// How far `t` (a rigid transform in the model frame) moves the surface off itself.
    pub fn displacement(&self, t: &DMat4) -> Displacement {
        let mut stack = Vec::with_capacity(64);
        Displacement::from_distances(
            self.samples.iter().map(|p| self.surface.distance_sq(t.transform_point3(*p), &mut stack).sqrt()).collect(),
        )
    }

    /// The worst displacement over a family of transforms.
    pub fn worst_displacement(&self, ts: &[DMat4]) -> Displacement {
        ts.iter().map(|t| self.displacement(t)).fold(Displacement::default(), Displacement::worst)
    }
}

/// SplitMix64: a small, fixed, platform-independent random stream.
pub(super) struct SplitMix64(pub(super) u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub(super) fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}
