//! Scene sampling: from a sample's key to the camera, the object pose and the appearance. Pure
//! and seeded; the robot and the grasp loop replace the free-floating object pose later.

pub mod drawable;
pub mod environment;
pub mod robot;

use glam::{DAffine3, DMat3, DQuat, DVec3};
use rand::Rng;
use vt_dataset::Pose;
use vt_randomizers::{Appearance, AppearanceContext, SampleKey, SampleStream, sample_appearance, uniform_rotation};

use crate::config::Config;

/// Everything that is decided before rendering.
#[derive(Debug, Clone)]
pub struct SampledScene {
    pub t_world_camera: Pose,
    pub t_world_object: Pose,
    pub appearance: Appearance,
}

/// A rigid transform as a dataset pose.
pub fn pose_of(t: &DAffine3) -> Pose {
    Pose::from_rt(DQuat::from_mat3(&t.matrix3), t.translation)
}

/// OpenCV camera frame (x right, y down, z forward) at `position` looking at `target`, world z up.
pub fn look_at(position: DVec3, target: DVec3) -> Pose {
    let z = (target - position).normalize();
    let x = z.cross(DVec3::Z).normalize();
    let y = z.cross(x);
    Pose::from_rt(DQuat::from_mat3(&DMat3::from_cols(x, y, z)), position)
}

/// The camera, the free object pose (replaced by the grasp loop's when there is a robot) and the
/// appearance (canonical or randomized, `randomization:`) of one sample.
pub fn sample_scene(config: &Config, key: &SampleKey, ctx: &AppearanceContext) -> SampledScene {
    let cam = &config.camera;
    let appearance = sample_appearance(&config.randomization, key, ctx);
    // Camera jitter: an offset in the camera's own frame.
    let (dt, dr) = appearance.camera_offset;
    let t_world_camera =
        look_at(DVec3::from_array(cam.position), DVec3::from_array(cam.look_at)).compose(&Pose::from_rt(DQuat::from_scaled_axis(dr), dt));
    let mut rng = SampleStream::sample(key, "object_pose");
    let w = &config.scene.workspace;
    let pos =
        DVec3::new(rng.random_range(w.min[0]..=w.max[0]), rng.random_range(w.min[1]..=w.max[1]), rng.random_range(w.min[2]..=w.max[2]));
    let rot = uniform_rotation(&mut rng);
    SampledScene { t_world_camera, t_world_object: Pose::from_rt(rot, pos), appearance }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_follows_opencv() {
        let t = look_at(DVec3::new(0.0, -1.0, 0.0), DVec3::ZERO);
        let r = DMat3::from_quat(t.rotation());
        assert!((r.z_axis - DVec3::Y).length() < 1e-9, "z forward");
        assert!((r.x_axis - DVec3::X).length() < 1e-9, "x right");
        assert!((r.y_axis + DVec3::Z).length() < 1e-9, "y down");
    }
}
