//! What one sample shows of its object, as the refiner uses it (camera frame, OpenCV): the
//! object's depth points (the mask's pixels with depth), the tactile points, and the free space
//! the depth image proves (where the camera saw past a surface, no object surface can be).

use glam::DVec3;
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;

/// The depth image and mask of a sample, for the free-space test.
#[derive(Debug, Clone)]
pub struct FreeSpace {
    pub width: usize,
    pub height: usize,
    /// `fx, fy, cx, cy`.
    pub intrinsics: [f64; 4],
    /// z-depth (m), 0: no surface.
    pub depth: Vec<f32>,
    /// Whether the pixel shows the object.
    pub object: Vec<bool>,
}

impl FreeSpace {
    /// Whether a surface point at `p` (camera frame) that faces the camera contradicts the
    /// image: it projects onto a pixel that is not the object's and where the camera saw farther
    /// than `p` by more than `margin` (or nothing at all). Points outside the image or behind the
    /// camera prove nothing.
    pub fn violated(&self, p: DVec3, margin: f64) -> bool {
        if p.z <= 1e-6 {
            return false;
        }
        let [fx, fy, cx, cy] = self.intrinsics;
        let (u, v) = ((fx * p.x / p.z + cx).round(), (fy * p.y / p.z + cy).round());
        if u < 0.0 || v < 0.0 || u >= self.width as f64 || v >= self.height as f64 {
            return false;
        }
        let i = v as usize * self.width + u as usize;
        if self.object[i] {
            return false;
        }
        let d = self.depth[i] as f64;
        d <= 0.0 || d > p.z + margin
    }
}

/// A sample's observation of its object.
#[derive(Debug, Clone)]
pub struct Observation {
    /// Depth points of the object's pixels (camera frame), a seeded subset when there are many.
    pub depth: Vec<DVec3>,
    /// Tactile points (camera frame), a seeded subset when there are many.
    pub touch: Vec<DVec3>,
    pub free_space: Option<FreeSpace>,
}

impl Observation {
    /// From a decoded sample: at most `max_depth` depth points and `max_touch` tactile points,
    /// drawn with a stream seeded by the sample's index (the same subset on every run).
    pub fn from_sample(s: &vt_dataset::Sample, max_depth: usize, max_touch: usize) -> Self {
        let (w, h) = (s.width as usize, s.height as usize);
        let (fx, fy, cx, cy) = (s.fx(), s.fy(), s.cx(), s.cy());
        let object: Vec<bool> = s.mask.iter().map(|&m| m == s.info.mask_id).collect();
        let mut depth = Vec::new();
        for (i, (&is_object, &z)) in object.iter().zip(&s.depth).enumerate() {
            if is_object && z > 0.0 {
                let (r, c, z) = ((i / w) as f64, (i % w) as f64, z as f64);
                depth.push(DVec3::new((c - cx) * z / fx, (r - cy) * z / fy, z));
            }
        }
        let touch: Vec<DVec3> =
            s.tactile.as_ref().map(|t| t.points.iter().map(|p| DVec3::from_array(p.position.map(f64::from))).collect()).unwrap_or_default();
        let mut rng = ChaCha8Rng::seed_from_u64(0x0b5e_0000 ^ s.index);
        Observation {
            depth: subset(depth, max_depth, &mut rng),
            touch: subset(touch, max_touch, &mut rng),
            free_space: Some(FreeSpace { width: w, height: h, intrinsics: [fx, fy, cx, cy], depth: s.depth.clone(), object }),
        }
    }

    /// The same observation with other tactile points (the touch control) or none.
    pub fn with_touch(&self, touch: Vec<DVec3>) -> Self {
        Observation { depth: self.depth.clone(), touch, free_space: self.free_space.clone() }
    }
}

/// At most `n` of `points`, in their order (a seeded choice when there are more).
fn subset(points: Vec<DVec3>, n: usize, rng: &mut ChaCha8Rng) -> Vec<DVec3> {
    if points.len() <= n {
        return points;
    }
    let mut keep = sample(rng, points.len(), n).into_vec();
    keep.sort_unstable();
    keep.into_iter().map(|i| points[i]).collect()
}
