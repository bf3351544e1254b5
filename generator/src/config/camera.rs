//! `camera:` the main RGB-D camera's image size, intrinsics, pose and noise.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    pub width: u32,
    pub height: u32,
    /// Pinhole intrinsics in pixels (FORMAT.md pixel-centre convention) …
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<Intrinsics>,
    /// … or a vertical field of view in degrees (square pixels, centred principal point). With
    /// neither, the paper camera's: a 615 px focal length at 480 rows, scaled with `height`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_y_deg: Option<f64>,
    /// Camera position in the world frame (metres).
    pub position: [f64; 3],
    /// World point the optical axis goes through.
    pub look_at: [f64; 3],
    pub near: f64,
    pub far: f64,
    /// RGB-D sensor noise (off by default): the noisy depth goes to `/camera/depth_noisy`, the
    /// clean one stays the ground truth.
    #[serde(default, skip_serializing_if = "super::is_default")]
    pub noise: super::noise::CameraNoiseConfig,
}

/// The paper camera's focal length (pixels) at 480 rows.
const PAPER_FOCAL_PX_AT_480: f64 = 615.0;

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            width: 640,
            height: 480,
            intrinsics: None,
            fov_y_deg: None,
            // The paper camera: 0.75 m in front of the robot's workspace, looking down at it.
            position: [0.0, -0.75, 0.55],
            look_at: [0.0, 0.0, 0.28],
            near: 0.05,
            far: 10.0,
            noise: Default::default(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl CameraConfig {
    /// The intrinsics, from `intrinsics`, derived from `fov_y_deg`, or the paper camera's focal
    /// length scaled to the image (615 px at 640 x 480: the paper's intrinsics exactly).
    pub fn k(&self) -> Intrinsics {
        let f = match (self.intrinsics, self.fov_y_deg) {
            (Some(k), _) => return k,
            (None, Some(fov)) => 0.5 * self.height as f64 / (0.5 * fov.to_radians()).tan(),
            (None, None) => PAPER_FOCAL_PX_AT_480 * self.height as f64 / 480.0,
        };
        Intrinsics { fx: f, fy: f, cx: (self.width as f64 - 1.0) / 2.0, cy: (self.height as f64 - 1.0) / 2.0 }
    }
}

impl Check for CameraConfig {
    /// Image size, intrinsics or field of view, clip planes, noise models, the camera's aim.
    // `!(a <= b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.width), 8, 8192);
        c.range(field!(self.height), 8, 8192);
        match (&self.intrinsics, self.fov_y_deg) {
            (Some(_), Some(_)) => c.key(key!(self.fov_y_deg)).fail("give either intrinsics or fov_y_deg, not both"),
            (None, None) => {}
            (None, Some(f)) => c.key(key!(self.fov_y_deg)).within(f, 1.0, 170.0),
            (Some(k), None) => {
                let mut intrinsics = c.key(key!(self.intrinsics));
                intrinsics.range(field!(k.fx), 1.0, 1e6);
                intrinsics.range(field!(k.fy), 1.0, 1e6);
                intrinsics.range(field!(k.cx), -0.5, self.width as f64 - 0.5);
                intrinsics.range(field!(k.cy), -0.5, self.height as f64 - 0.5);
            }
        }
        c.range(field!(self.near), 1e-4, 100.0);
        c.section(field!(self.noise));
        if !(self.far > self.near && self.far <= 1000.0) {
            c.key(key!(self.far)).fail(format!("{} is out of range: allowed near ({}) < far <= 1000", self.far, self.near));
        }
        let d: f64 = (0..3).map(|i| (self.look_at[i] - self.position[i]).powi(2)).sum::<f64>().sqrt();
        if !(d > 1e-6) {
            c.key(key!(self.look_at)).fail("look_at must differ from position");
        } else if ((self.look_at[0] - self.position[0]).abs() + (self.look_at[1] - self.position[1]).abs()) < 1e-9 {
            c.key(key!(self.look_at)).fail("the camera must not look straight up or down (world z is the up direction)");
        }
        for (key, point) in [field!(self.position), field!(self.look_at)] {
            for (i, v) in point.iter().enumerate() {
                c.key(key).index(i).within(*v, -100.0, 100.0);
            }
        }
    }
}
