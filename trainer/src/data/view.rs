//! A decoded sample as the pipeline keeps it ([`ObjectView`]) and its preparation into fixed-size
//! network inputs ([`prepare`]).

use super::*;

/// What the pipeline keeps of a decoded sample: the object's crop, pixels, points, touch, pose.
#[derive(Debug, Clone)]
pub struct ObjectView {
    /// The sample's index in its split.
    pub index: u64,
    /// Its object's `object_index`.
    pub object: usize,
    /// Bounding box of the mask, `[row_min, row_max, col_min, col_max)`; zeros when not visible.
    pub bbox: [usize; 4],
    /// The RGB crop by `bbox`, row-major bytes.
    pub crop: Vec<u8>,
    /// Object pixels with depth, `(row, col)` in the full image, row-major order.
    pub pixels: Vec<(u32, u32)>,
    /// Their camera-frame points.
    pub points: Vec<[f32; 3]>,
    /// The tactile point cloud (camera frame); empty without touch.
    pub tactile: Vec<[f32; 3]>,
    pub rotation: DQuat,
    pub translation: DVec3,
    /// The paper's occlusion level (NaN when the dataset has none).
    pub occlusion: f32,
    /// The grasp (trajectory) and the arm pose (instance) of the sample, from `/sample/info`
    /// (`u32::MAX` when absent): samples of one trajectory share a grasp.
    pub trajectory: u32,
    pub instance: u32,
    /// An episode frame's time since the episode's start (s); NaN for a snapshot.
    pub time_s: f64,
}

impl ObjectView {
    /// Extracts the view of a full sample.
    pub fn from_sample(s: &vt_dataset::Sample, object: usize, depth: DepthSource) -> Result<Self> {
        let (w, h) = (s.width as usize, s.height as usize);
        let mask_id = s.info.mask_id;
        let depth_img = match depth {
            DepthSource::Exact => &s.depth,
            DepthSource::Noisy => s
                .depth_noisy
                .as_ref()
                .ok_or_else(|| anyhow!("sample {}: data.depth is `noisy` but the dataset has no /camera/depth_noisy", s.index))?,
        };
        let (fx, fy, cx, cy) = (s.fx(), s.fy(), s.cx(), s.cy());
        let (mut rmin, mut rmax, mut cmin, mut cmax) = (usize::MAX, 0, usize::MAX, 0);
        let mut pixels = Vec::new();
        let mut points = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let i = r * w + c;
                if s.mask[i] != mask_id {
                    continue;
                }
                (rmin, rmax, cmin, cmax) = (rmin.min(r), rmax.max(r + 1), cmin.min(c), cmax.max(c + 1));
                let z = depth_img[i] as f64;
                if z > 0.0 {
                    pixels.push((r as u32, c as u32));
                    points.push([((c as f64 - cx) * z / fx) as f32, ((r as f64 - cy) * z / fy) as f32, z as f32]);
                }
            }
        }
        let (bbox, crop) = if pixels.is_empty() {
            ([0; 4], Vec::new())
        } else {
            let crop = (rmin..rmax).flat_map(|r| s.rgb[(r * w + cmin) * 3..(r * w + cmax) * 3].iter().copied()).collect();
            ([rmin, rmax, cmin, cmax], crop)
        };
        let tactile = s.tactile.as_ref().map(|t| t.points.iter().map(|p| p.position).collect()).unwrap_or_default();
        let occlusion = s.info.occlusion.map_or(f32::NAN, |o| o.level as f32);
        Ok(ObjectView {
            index: s.index,
            object,
            bbox,
            crop,
            pixels,
            points,
            tactile,
            rotation: s.t_camera_object.rotation(),
            translation: s.t_camera_object.translation(),
            occlusion,
            trajectory: s.info.trajectory,
            instance: s.info.instance,
            time_s: s.episode.as_ref().map_or(f64::NAN, |e| e.time_ns as f64 * 1e-9),
        })
    }

    pub fn visible(&self) -> bool {
        !self.pixels.is_empty()
    }
}

/// One sample as the network and the loss take it (fixed shapes).
#[derive(Debug, Clone, Default)]
pub struct Prepared {
    pub index: u64,
    /// Dataset `object_index` and head slot.
    pub object: usize,
    pub slot: usize,
    /// Closest-point (ADD-S) loss for this sample.
    pub symmetric: bool,
    pub occlusion: f32,
    pub trajectory: u32,
    pub instance: u32,
    /// An episode frame's time (s, [`ObjectView::time_s`]); NaN for a snapshot.
    pub time_s: f64,
    /// `(n, 3)` camera-frame points; zeros when `cloud_count == 0`.
    pub cloud: Vec<f32>,
    /// `(n,)` pixel of each point in the flattened `S × S` crop.
    pub choose: Vec<i64>,
    /// `(3, S, S)` normalised crop, channel-first.
    pub img: Vec<f32>,
    /// Object pixels with depth the points were drawn from (0: not visible).
    pub cloud_count: usize,
    /// `(n_t, 3)` tactile points; zeros when `tactile_count == 0`.
    pub tactile: Vec<f32>,
    pub tactile_count: usize,
    /// `(M, 3)` model points, object frame.
    pub model_points: Vec<f32>,
    /// Ground truth `T_camera_object` (translation noise included in training).
    pub rotation: DQuat,
    pub translation: DVec3,
}

/// What [`prepare`] needs besides the sample.
#[derive(Debug, Clone)]
pub struct PrepareOptions {
    pub data: DataConfig,
    pub augment: AugmentConfig,
    pub seed: u64,
    pub split: String,
    /// Head slot per dataset object index (`None`: not trained on).
    pub slots: Vec<Option<usize>>,
    /// Per dataset object index: trained with the closest-point loss (`train.symmetric_loss`).
    pub closest_point: Vec<bool>,
}

impl PrepareOptions {
    /// The random streams of sample `index` in `epoch` (0: depth points, 1: tactile, 2: model
    /// points, 3: augmentation).
    fn rng(&self, epoch: u64, index: u64, stream: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(&[self.seed, epoch, split_key(&self.split), index]));
        rng.set_stream(stream);
        rng
    }
}

/// Maps a decoded sample to the network's inputs (see the module docs).
pub fn prepare(view: &ObjectView, model: &ObjectModel, opts: &PrepareOptions, epoch: u64) -> Prepared {
    let d = &opts.data;
    let epoch = if d.resample { epoch } else { 0 };
    let (n, s) = (d.n_points, d.crop_size);
    let mut rng_cloud = opts.rng(epoch, view.index, 0);
    let mut cloud = vec![0.0f32; n * 3];
    let mut choose = vec![0i64; n];
    let mut img = vec![0.0f32; 3 * s * s];
    if view.visible() {
        let [rmin, rmax, cmin, cmax] = view.bbox;
        let (h, w) = (rmax - rmin, cmax - cmin);
        for (k, i) in draw(&mut rng_cloud, view.pixels.len(), n).into_iter().enumerate() {
            cloud[k * 3..k * 3 + 3].copy_from_slice(&view.points[i]);
            let (r, c) = view.pixels[i];
            choose[k] = (resized_cell(r as usize - rmin, h, s) * s + resized_cell(c as usize - cmin, w, s)) as i64;
        }
        let mut crop = resize_bilinear(&view.crop, h, w, s);
        if opts.augment.color_jitter > 0.0 {
            color_jitter(&mut crop, opts.augment.color_jitter, &mut opts.rng(epoch, view.index, 3));
        }
        // HWC bytes-as-float -> CHW normalised.
        for p in 0..s * s {
            for k in 0..3 {
                img[k * s * s + p] = (crop[p * 3 + k] / 255.0 - IMAGENET_MEAN[k]) / IMAGENET_STD[k];
            }
        }
    }
    let nt = d.n_tactile;
    let mut tactile = vec![0.0f32; nt * 3];
    if !view.tactile.is_empty() {
        let mut rng = opts.rng(epoch, view.index, 1);
        for (k, i) in draw(&mut rng, view.tactile.len(), nt).into_iter().enumerate() {
            tactile[k * 3..k * 3 + 3].copy_from_slice(&view.tactile[i]);
        }
    }
    let model_points = model.sample_surface(d.n_model_points, &mut opts.rng(epoch, view.index, 2)).concat();
    let mut translation = view.translation;
    let noise = opts.augment.translation_noise_m;
    if noise > 0.0 {
        // One offset for the whole sample: the scene moved, the inputs and the truth alike.
        let mut rng = opts.rng(epoch, view.index, 4);
        let off: [f32; 3] = std::array::from_fn(|_| rng.random_range(-noise..=noise));
        translation += DVec3::from_array(off.map(f64::from));
        for (k, v) in cloud.iter_mut().enumerate().take(if view.visible() { n * 3 } else { 0 }) {
            *v += off[k % 3];
        }
        for (k, v) in tactile.iter_mut().enumerate().take(if view.tactile.is_empty() { 0 } else { nt * 3 }) {
            *v += off[k % 3];
        }
    }
    Prepared {
        index: view.index,
        object: view.object,
        slot: opts.slots[view.object].unwrap_or(0),
        symmetric: opts.closest_point.get(view.object).copied().unwrap_or(false),
        occlusion: view.occlusion,
        trajectory: view.trajectory,
        instance: view.instance,
        time_s: view.time_s,
        cloud,
        choose,
        img,
        cloud_count: view.pixels.len(),
        tactile,
        tactile_count: view.tactile.len(),
        model_points,
        rotation: view.rotation,
        translation,
    }
}

/// Brightness, contrast and saturation jitter in place (values 0..255, HWC), factors `1 ± j`.
fn color_jitter(img: &mut [f32], j: f32, rng: &mut impl Rng) {
    let mut factor = || rng.random_range(1.0 - j..=1.0 + j);
    let (brightness, contrast, saturation) = (factor(), factor(), factor());
    let mean = img.iter().sum::<f32>() / img.len() as f32;
    for px in img.chunks_exact_mut(3) {
        let grey = 0.299 * px[0] + 0.587 * px[1] + 0.114 * px[2];
        for v in px.iter_mut() {
            let sat = grey + (*v - grey) * saturation;
            *v = ((mean + (sat - mean) * contrast) * brightness).clamp(0.0, 255.0);
        }
    }
}
