//! Prepared samples of one batch, and their tensors and targets.

use super::*;

/// Prepared samples of one batch, turned into tensors on demand.
#[derive(Debug, Clone, Default)]
pub struct Batch {
    pub samples: Vec<Prepared>,
}

/// The ground truth of a batch, as the loss takes it.
#[derive(Debug, Clone)]
pub struct Targets {
    /// `(B, M, 3)` model points, object frame.
    pub model_points: Tensor<3>,
    /// `(B, 3, 3)` true rotations.
    pub rotation: Tensor<3>,
    /// `(B, 3)` true translations.
    pub translation: Tensor<2>,
    /// Per sample: closest-point (symmetric) loss.
    pub symmetric: Vec<bool>,
    /// The same model points on the host, for the closest-point search.
    pub host_points: Vec<Vec<[f32; 3]>>,
    pub host_rotation: Vec<[f32; 9]>,
    pub host_translation: Vec<[f32; 3]>,
}

impl Batch {
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The batch cut into `parts` consecutive shards of near-equal size (the first ones one
    /// sample larger), none empty.
    pub fn split(&self, parts: usize) -> Vec<Batch> {
        let parts = parts.clamp(1, self.len().max(1));
        let (base, extra) = (self.len() / parts, self.len() % parts);
        let mut start = 0;
        (0..parts)
            .map(|k| {
                let len = base + usize::from(k < extra);
                let shard = Batch { samples: self.samples[start..start + len].to_vec() };
                start += len;
                shard
            })
            .collect()
    }

    /// The network inputs on `device`.
    pub fn inputs(&self, device: &Device) -> PoseInput {
        let b = self.samples.len();
        let first = &self.samples[0];
        let n = first.choose.len();
        let nt = first.tactile.len() / 3;
        let s = ((first.img.len() / 3) as f64).sqrt() as usize;
        let cat = |f: &dyn Fn(&Prepared) -> &[f32]| self.samples.iter().flat_map(|p| f(p).iter().copied()).collect::<Vec<f32>>();
        PoseInput {
            img: Tensor::from_data(TensorData::new(cat(&|p| &p.img), [b, 3, s, s]), device),
            choose: Tensor::from_data(
                TensorData::new(self.samples.iter().flat_map(|p| p.choose.iter().copied()).collect::<Vec<i64>>(), [b, n]),
                device,
            ),
            cloud: Tensor::from_data(TensorData::new(cat(&|p| &p.cloud), [b, n, 3]), device),
            tactile: Tensor::from_data(TensorData::new(cat(&|p| &p.tactile), [b, nt, 3]), device),
            has_touch: Tensor::from_data(
                TensorData::new(self.samples.iter().map(|p| f32::from(u8::from(p.tactile_count > 0))).collect::<Vec<f32>>(), [b, 1]),
                device,
            ),
            object: Tensor::<1, Int>::from_data(
                TensorData::new(self.samples.iter().map(|p| p.slot as i64).collect::<Vec<i64>>(), [b]),
                device,
            ),
        }
    }

    /// The loss targets on `device`.
    pub fn targets(&self, device: &Device) -> Targets {
        let b = self.samples.len();
        let m = self.samples[0].model_points.len() / 3;
        let host_rotation: Vec<[f32; 9]> = self.samples.iter().map(|p| matrix_rows(p.rotation)).collect();
        let host_translation: Vec<[f32; 3]> = self.samples.iter().map(|p| p.translation.as_vec3().to_array()).collect();
        Targets {
            model_points: Tensor::from_data(
                TensorData::new(self.samples.iter().flat_map(|p| p.model_points.iter().copied()).collect::<Vec<f32>>(), [b, m, 3]),
                device,
            ),
            rotation: Tensor::from_data(TensorData::new(host_rotation.concat(), [b, 3, 3]), device),
            translation: Tensor::from_data(TensorData::new(host_translation.concat(), [b, 3]), device),
            symmetric: self.samples.iter().map(|p| p.symmetric).collect(),
            host_points: self.samples.iter().map(|p| p.model_points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()).collect(),
            host_rotation,
            host_translation,
        }
    }
}
