//! What the robot's and the camera's sensors make of a rendered scene: the tactile point cloud
//! from the 12 phalanx depth views, and a noisy RGB-D reading of the exact main-camera images.

pub mod rgbd_noise;
pub mod tactile;
