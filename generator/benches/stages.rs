//! Criterion micro-benchmarks of the sample path's hot stages, each alone: one physics step of the
//! grasped hand, a grasp trajectory, the main 640x480 render (PBR, shadow map, depth, mask,
//! silhouette), the 12 pad depth views, the occlusion level, writing one sample to a zstd
//! shard, one optical tactile image per preset on the CPU, its marker field, and the optical
//! shading on the GPU. `cargo bench -p vtgen --bench stages` (rendering runs on whatever adapter wgpu picks:
//! lavapipe on a machine without a GPU). `vtgen bench` measures the stages inside a real run.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{DAffine3, DMat4, DQuat, DVec3};
use vt_dataset::{Compression, Pose, Sample, SampleInfo, ShardMeta, ShardWriter, Split, TactileData};
use vt_objects::{Catalog, TexturedMesh, procedural_mesh};
use vt_robot::Robot;
use vtgen::annotate::occlusion::{model_points, occlusion_level};
use vtgen::config::{GraspConfig, Intrinsics, PhysicsConfig, RendererConfig};
use vtgen::physics::grasp::{GraspContext, TrajectoryKey, simulate_trajectory};
use vtgen::physics::{HandPhysics, PhysicsObject, PhysicsSettings, RapierHand};
use vtgen::render::{DepthView, Draw, DrawRole, Lighting, Renderer, View, WgpuRenderer};
use vtgen::scene::environment::floor_mesh;
use vtgen::scene::look_at;

const OBJECT: &str = "005_tomato_soup_can";

fn physics_object() -> PhysicsObject {
    let entry = Catalog::builtin().get(OBJECT).expect("in the catalogue").clone();
    PhysicsObject { points: procedural_mesh(&entry).positions, mass: entry.mass }
}

fn settings() -> PhysicsSettings {
    PhysicsSettings::from(&PhysicsConfig::default())
}

fn physics(c: &mut Criterion) {
    let robot = Robot::default_robot();
    let object = physics_object();
    let mut group = c.benchmark_group("physics");
    // One step with the fingers closed around the can (contacts active), as during an arm move.
    let mut hand = RapierHand::new(&robot, settings()).expect("hand");
    let grasp = GraspConfig::default().with_robot_defaults(&robot);
    hand.reset(&object, DAffine3::from_translation(DVec3::new(grasp.palm_surface_x + 0.04, 0.0, 0.06)), &vec![0.0; robot.hand.len()])
        .expect("reset");
    let close: Vec<f64> = grasp.close.iter().map(|c| c.unwrap_or(0.0)).collect();
    hand.set_targets(&close);
    hand.set_gravity(DVec3::new(-9.81, 0.0, 0.0));
    for _ in 0..150 {
        hand.step();
    }
    group.bench_function("step (hand closed on the soup can)", |b| b.iter(|| hand.step()));
    // A whole trajectory of 5 instances: grasp, then 5 arm moves with their holds and checks.
    let t_world_base = DAffine3::from_rotation_translation(DQuat::from_rotation_z(std::f64::consts::PI), DVec3::new(0.0, 0.5, 0.0));
    let ctx = GraspContext::new(&robot, t_world_base, &grasp, settings().timestep, DVec3::new(0.0, -0.75, 0.55));
    group.sample_size(10);
    group.bench_function("trajectory of 5 instances (soup can)", |b| {
        b.iter(|| {
            let mut log = vtgen::physics::grasp::GraspLog::default();
            black_box(
                simulate_trajectory(
                    &ctx,
                    &mut hand,
                    &object,
                    TrajectoryKey { seed: 1, object_id: OBJECT, trajectory: 0, instances: 5 },
                    &mut log,
                )
                .expect("a grasp holds"),
            )
        })
    });
    group.finish();
}

/// The paper's camera over a floor with the can standing on it at the workspace centre.
struct Scene {
    renderer: WgpuRenderer,
    view: View,
    draws: Vec<Draw>,
    lighting: Lighting,
    t_camera_object: DAffine3,
    mesh: TexturedMesh,
}

fn scene() -> Scene {
    let mut renderer = WgpuRenderer::new(&RendererConfig::default()).expect("an adapter");
    let entry = Catalog::builtin().get(OBJECT).expect("in the catalogue").clone();
    let mesh = procedural_mesh(&entry);
    let floor = renderer.upload_mesh(&floor_mesh()).expect("upload");
    let can = renderer.upload_mesh(&mesh).expect("upload");
    let cam = look_at(DVec3::new(0.0, -0.75, 0.55), DVec3::new(0.0, 0.0, 0.28));
    let view = View {
        width: 640,
        height: 480,
        k: Intrinsics { fx: 615.0, fy: 615.0, cx: 319.5, cy: 239.5 },
        near: 0.05,
        far: 10.0,
        t_world_camera: cam.matrix(),
    };
    let t_world_object = DAffine3::from_translation(DVec3::new(0.0, 0.0, 0.5 * entry.extents[2]));
    let draws = vec![
        Draw { mesh: floor, t_world_model: DMat4::IDENTITY, mask_id: 0, role: DrawRole::Environment },
        Draw { mesh: can, t_world_model: DMat4::from(t_world_object), mask_id: 1, role: DrawRole::Target },
    ];
    let lighting = Lighting::spot(DVec3::new(0.3, -0.3, 1.2), DVec3::new(0.0, 0.0, 0.1), [3.0; 3], [0.3; 3]);
    let t_camera_object = DAffine3::from_mat4(cam.inverse().matrix()) * t_world_object;
    Scene { renderer, view, draws, lighting, t_camera_object, mesh }
}

// Long on purpose: one criterion group per renderer stage on the same scene, listed in order.
fn rendering(c: &mut Criterion) {
    let mut s = scene();
    let mut group = c.benchmark_group("render");
    group.sample_size(20);
    group.bench_function("main view 640x480 (colour, depth, mask, silhouette, shadows)", |b| {
        b.iter(|| black_box(s.renderer.render(&s.view, &s.lighting, &s.draws).expect("render")))
    });
    // 12 pads of 2 cm x 2 cm around the can's side, 1 mm off its surface, looking at it.
    let can = s.draws[1];
    let radius = 0.5 * Catalog::builtin().get(OBJECT).expect("in the catalogue").extents[0];
    let views: Vec<DepthView> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            let out = DVec3::new(a.cos(), a.sin(), 0.0);
            let centre = DAffine3::from_mat4(can.t_world_model).transform_point3(out * (radius + 0.001));
            DepthView {
                width: 32,
                height: 32,
                half_x: 0.01,
                half_y: 0.01,
                near: -0.005,
                far: 0.02,
                t_world_camera: look_at(centre, centre - out).matrix(),
                perspective_standoff: None,
            }
        })
        .collect();
    group.bench_function("12 pad depth views 32x32 (one pass)", |b| {
        b.iter(|| black_box(s.renderer.render_depth_views(&views, &[can]).expect("render")))
    });
    // Two GelSight Minis pressed 0.5 mm into the can's side: their depth views alone, then with the
    // optical shading on the GPU in the same submission (`robot.tactile.optical_shading: gpu`).
    let sensor = vtgen::config::OpticalConfig { markers: Some(Default::default()), ..Default::default() }.resolve();
    let optical_views: Vec<DepthView> = [0.0f64, std::f64::consts::PI]
        .iter()
        .map(|a| {
            let out = DVec3::new(a.cos(), a.sin(), 0.0);
            let centre = DAffine3::from_mat4(can.t_world_model).transform_point3(out * (radius + 0.001));
            DepthView {
                width: sensor.image_size[0],
                height: sensor.image_size[1],
                half_x: sensor.sensing_area_mm[0] * 0.5e-3,
                half_y: sensor.sensing_area_mm[1] * 0.5e-3,
                near: -0.005,
                far: (sensor.gel_thickness_mm + 0.1) * 1e-3,
                t_world_camera: look_at(centre, centre - out).matrix(),
                perspective_standoff: None,
            }
        })
        .collect();
    let shading: Vec<_> = (0..2).map(|k| vtgen::sensors::optical::gel_shading(&sensor, k).expect("the LED model")).collect();
    group.bench_function("2 optical depth views 320x240 (one pass)", |b| {
        b.iter(|| black_box(s.renderer.render_depth_views(&optical_views, &[can]).expect("render")))
    });
    group.bench_function("2 optical depth views 320x240 + their GPU shading (one pass)", |b| {
        b.iter(|| black_box(s.renderer.render_depth_views_shaded(&optical_views, &shading, &[can]).expect("render")))
    });
    group.finish();
    // What the CPU still does per image after the GPU's shading (markers, noise, 8 bits), against
    // the whole CPU model from the same depth.
    let (depth, shaded) = s.renderer.render_depth_views_shaded(&optical_views, &shading, &[can]).expect("render");
    let shaded = shaded.expect("the wgpu renderer shades");
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
    let mut group = c.benchmark_group("optical tactile image");
    group.bench_function("GelsightMini 320x240 on the CPU from the GPU's shading (markers, noise)", |b| {
        b.iter(|| black_box(vtgen::sensors::optical::optical_image_shaded(&sensor, &shaded[0], None, Some(&mut rng)).0))
    });
    group.bench_function("GelsightMini 320x240 on the CPU from the same depth (shading, markers, noise)", |b| {
        b.iter(|| black_box(vtgen::sensors::optical::optical_image(&sensor, Some(&depth[0]), None, Some(&mut rng))))
    });
    group.finish();

    let img = s.renderer.render(&s.view, &s.lighting, &s.draws).expect("render");
    let points: Vec<DVec3> = model_points(&s.mesh, 2000).iter().map(|p| s.t_camera_object.transform_point3(*p)).collect();
    c.bench_function("occlusion level (2000 model points, 3 mm)", |b| {
        b.iter(|| black_box(occlusion_level(&points, &img.depth, img.width, img.height, &s.view.k, 0.003)))
    });

    let dir = tempfile::tempdir().expect("temp dir");
    let meta = ShardMeta {
        generator: "bench".into(),
        seed: 0,
        config_sha256: String::new(),
        split: "bench".into(),
        shard_index: 0,
        first_sample: 0,
        sample_count: u64::MAX,
        extra: Default::default(),
    };
    let mut writer = ShardWriter::create(&dir.path().join("bench.mcap"), &meta, Compression::Zstd { level: 3 }).expect("shard");
    let identity = Pose::from_rt(DQuat::IDENTITY, DVec3::ZERO);
    let sample = Sample {
        index: 0,
        width: img.width,
        height: img.height,
        rgb: img.rgb.clone(),
        depth: img.depth.clone(),
        depth_noisy: None,
        mask: img.mask.clone(),
        k: [615.0, 0.0, 319.5, 0.0, 615.0, 239.5, 0.0, 0.0, 1.0],
        t_camera_object: identity,
        t_world_camera: identity,
        t_world_object: identity,
        extra_transforms: Vec::new(),
        info: SampleInfo {
            split: Split::Train,
            index: 0,
            object_id: "005_tomato_soup_can".into(),
            object_index: 0,
            mask_id: vt_dataset::mask_ids::TARGET_OBJECT,
            trajectory: 0,
            instance: 0,
            randomized: false,
            appearance: serde_json::json!({"randomized": false}),
            distractors: Vec::new(),
            visible_pixels: 0,
            occlusion: None,
            t_world_camera: identity,
            t_camera_object: identity,
            robot: None,
            episode: None,
        },
        tactile: Some(TactileData {
            pads: Robot::default_robot().pad_names(),
            resolution: 32,
            depth: vec![vec![f32::INFINITY; 32 * 32]; 12],
            points: Vec::new(),
            optical: Vec::new(),
            forces: Vec::new(),
            marker_flow: Vec::new(),
        }),
        episode: None,
    };
    c.bench_function("write one 640x480 sample (zstd 3)", |b| b.iter(|| writer.write_sample(black_box(&sample)).expect("write")));
}

/// One optical tactile image per preset, from the depth of a 6 mm sphere pressed 0.8 mm into the
/// gel (markers and noise on), and the reference image alone.
fn optical(c: &mut Criterion) {
    use rand::SeedableRng;
    use vtgen::config::{OpticalConfig, OpticalPreset};
    use vtgen::sensors::optical::{ball_press_depth, optical_image, reference_image};
    let mut group = c.benchmark_group("optical tactile image");
    for preset in [OpticalPreset::GelsightMini, OpticalPreset::Digit] {
        let sensor = OpticalConfig { preset, markers: Some(Default::default()), ..Default::default() }.resolve();
        let [w, h] = sensor.image_size;
        let depth = ball_press_depth(&sensor, 0.006, 0.8e-3, [0.0, 0.0]);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        group.bench_function(format!("{preset:?} {w}x{h}, sphere pressed, markers, noise"), |b| {
            b.iter(|| black_box(optical_image(&sensor, Some(&depth), None, Some(&mut rng))))
        });
        group.bench_function(format!("{preset:?} {w}x{h}, reference"), |b| b.iter(|| black_box(reference_image(&sensor))));
        // The marker displacement field alone (FOTS's "marker field"): the gel's slopes under the
        // sphere and every marker's move, with a shear of 1 N along x over the pad.
        let field = vt_dataset::PadForceField {
            pad: "bench".into(),
            resolution: 16,
            cells: (0..256)
                .map(|i| vt_dataset::ForceCell {
                    position: [((i % 16) as f32 - 7.5) * 1e-3, ((i / 16) as f32 - 7.5) * 1e-3],
                    pressure: 2000.0,
                    shear: [1.0 / (0.0186 * 0.0143), 0.0],
                    slip: false,
                })
                .collect(),
        };
        let shear = vtgen::sensors::force_field::GelShear::new(&field, (0.0186, 0.0143), 50e3);
        group.bench_function(format!("{preset:?} {w}x{h}, marker field (slopes and every marker's move, with shear)"), |b| {
            b.iter(|| {
                let slopes = vtgen::sensors::optical::gel_slopes(&sensor, Some(&depth));
                black_box(vtgen::sensors::optical::marker_flow(&sensor, slopes.as_deref(), Some(&shear)))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, physics, rendering, optical);
criterion_main!(benches);
