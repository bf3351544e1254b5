//! What the robot's and the camera's sensors make of a rendered scene: the touch step (`touch`:
//! each pad's sensor, its reading and what the sample says of it), the tactile point cloud
//! from the pads' depth views, the optical tactile images of the pads that have that sensor, the
//! pads' force fields from the physics' contact forces, and a noisy RGB-D reading of the exact
//! main-camera images; and the optical sensor's fit to a real unit's presses.

pub mod force_field;
pub mod optical;
pub mod optical_fit;
pub mod rgbd_noise;
pub mod tactile;
pub mod touch;
