//! The optical images shaded on the GPU (`robot.tactile.optical_shading: gpu`, WGSL in the
//! submission of the depth views) against the CPU model, their reference: the same config and seed
//! give images equal within one 8-bit level, value for value, with markers, noise, sensor variation
//! and real contacts (`scenes/tiny-gripper.yaml`, on whatever adapter the machine has: lavapipe
//! here).

#[test]
fn gpu_shading_equals_the_cpu_model_within_one_level() {
    use crate::common::*;
    let cpu = tempdir();
    let gpu = tempdir();
    let small = ["--set", "sampling.trajectories_per_object=2"];
    generate(&root().join("scenes/tiny-gripper.yaml"), cpu.path(), &small);
    let mut args = small.to_vec();
    args.extend(["--set", "robot.tactile.optical_shading=gpu"]);
    generate(&root().join("scenes/tiny-gripper.yaml"), gpu.path(), &args);
    let (a, b) = (vt_dataset::DatasetReader::open(cpu.path()).unwrap(), vt_dataset::DatasetReader::open(gpu.path()).unwrap());
    let (mut values, mut differ, mut worst, mut touched) = (0usize, 0usize, 0u8, 0usize);
    for split in ["train", "test"] {
        for (x, y) in a.samples(split).unwrap().zip(b.samples(split).unwrap()) {
            let (x, y) = (x.unwrap(), y.unwrap());
            let (ox, oy) = (&x.tactile.as_ref().unwrap().optical, &y.tactile.as_ref().unwrap().optical);
            assert_eq!(ox.len(), oy.len());
            for (p, q) in ox.iter().zip(oy) {
                assert_eq!((p.pad.as_str(), p.width, p.height), (q.pad.as_str(), q.width, q.height));
                assert_eq!(p.reference, q.reference, "the references are the CPU's in both");
                for (u, v) in p.image.iter().zip(&q.image) {
                    let d = u.abs_diff(*v);
                    worst = worst.max(d);
                    differ += (d > 0) as usize;
                }
                values += p.image.len();
                touched += p.image.iter().zip(&p.reference).any(|(i, r)| i.abs_diff(*r) > 20) as usize;
            }
        }
    }
    eprintln!("{values} values: {differ} differ by one level, the largest difference {worst}; {touched} images with a contact");
    assert!(touched > 0, "no image shows a contact");
    assert!(worst <= 1, "a value differs by {worst} levels");
}
