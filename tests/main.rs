//! Workspace integration tests. They are compiled as tests of the `vtgen` package so they can run
//! the real binary; one test binary keeps link time low.

mod common;

mod bad_input;
mod bench;
mod bop_export;
mod contact_forces;
mod determinism;
mod episodes;
mod foxglove_scene;
mod grasping;
mod ground_truth;
mod jaco;
mod mesh_robot;
mod optical_calibration;
mod optical_shading;
mod own_robot;
mod pad_sensors;
mod panda;
mod render_geometry;
mod robot_meshes;
mod scale_out;
mod sensor_noise;
mod stats;
mod validate;
mod ycb_meshes;
