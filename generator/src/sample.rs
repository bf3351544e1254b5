//! One sample: scene sampling, the robot's recorded grasp state, rendering, and the ground truth
//! and metadata that go with it. A factory lives in one worker thread with its own renderer.

use std::time::Duration;

use anyhow::{Context, Result};
use glam::{DAffine3, DMat4};
use vt_dataset::{
    EpisodeData, EpisodeFrameInfo, GraspStats, OcclusionBin, OcclusionInfo, PlacedDistractor, Pose, RobotInfo, Sample, SampleInfo,
    SceneModel, Split, StateRecord, TactileData, frames, mask_ids,
};
use vt_objects::Texture;
use vt_randomizers::{AppearanceContext, ImageLibrary, ProceduralTexture, SampleKey, SampleStream};

use crate::annotate::occlusion::{model_points, occlusion_level};
use crate::assets::LoadedObject;
use crate::config::{Config, LoadedConfig, snap_depth_to_grid};
use crate::cpu_clock::StageClock;
use crate::physics::grasp::Trajectory;
use crate::physics::robot::RobotScene;
use crate::plan::{EpisodeTimeline, SampleRef};
use crate::render::{Draw, DrawRole, Lighting, Material, MeshHandle, Renderer, View};
use crate::scene::environment::{Distractor, backdrop_mesh, floor_mesh, glb_of, place_distractors};
use crate::scene::robot::{link_mesh, mask_id as robot_mask_id, pose_links};
use crate::scene::{SampledScene, pose_of, sample_scene};
use crate::sensors::touch::{TouchInput, TouchStep};

/// `texture` with each sRGB channel times its factor (alpha kept).
fn tinted(texture: &vt_objects::Texture, factors: [f32; 3]) -> vt_objects::Texture {
    let mut t = texture.clone();
    for px in t.rgba.chunks_exact_mut(4) {
        for (channel, factor) in px.iter_mut().zip(factors) {
            *channel = (*channel as f32 * factor).round().clamp(0.0, 255.0) as u8;
        }
    }
    t
}

fn texture_of(t: &ProceduralTexture) -> Texture {
    Texture { width: t.width, height: t.height, rgba: t.rgba.clone() }
}

/// A texture the renderer holds, so that it is uploaded only when it changes.
#[derive(Default)]
struct TextureSlot(Option<(ProceduralTexture, f32)>);

impl TextureSlot {
    fn set(&mut self, r: &mut dyn Renderer, mesh: MeshHandle, t: &ProceduralTexture, tile: f64) -> Result<()> {
        let scale = (1.0 / tile.max(1e-3)) as f32;
        if self.0.as_ref().is_none_or(|(old, s)| old != t || *s != scale) {
            r.set_texture(mesh, &texture_of(t), scale)?;
            self.0 = Some((t.clone(), scale));
        }
        Ok(())
    }
}

/// The robot's drawn links as the renderer holds them.
#[derive(Default)]
struct DrawnRobot {
    /// (link, mesh, mask id) of every drawn link.
    meshes: Vec<(usize, MeshHandle, u8)>,
    /// Each drawn link's own texture and material (with `randomization.robot_materials`).
    materials: Vec<(MeshHandle, vt_objects::Texture, Material)>,
    /// The links' meshes for Foxglove's 3D view.
    glbs: Vec<SceneModel>,
}

/// Uploads every drawn link of the robot, from its URDF's visuals (its meshes, or its primitives
/// where a robot's optional meshes are not there).
fn upload_robot(renderer: &mut dyn Renderer, cfg: &LoadedConfig, r: &RobotScene) -> Result<DrawnRobot> {
    let mut out = DrawnRobot::default();
    if !r.robot.model.visual_meshes_left_out.is_empty() {
        static SAID: std::sync::Once = std::sync::Once::new();
        SAID.call_once(|| {
            eprintln!(
                "vtgen: drawing the robot from primitives (no robot meshes: --robot-assets DIR, e.g. \
                     `--robot-assets \"$(scripts/robot-assets)\"`, draws the real meshes of {})",
                r.robot.name
            )
        });
    }
    for link in 0..r.robot.model.links.len() {
        let mesh = link_mesh(&r.robot.model, link);
        if let (Some(mesh), Some(id)) = (mesh, robot_mask_id(&r.robot, link)) {
            // Matte black hand (white tips), the arm's painted aluminium.
            let arm = mask_ids::ARM_LINKS.contains(&id) || id == mask_ids::ARM_LINK_SEVENTH;
            let material = if arm { Material { roughness: 0.45, metallic: 0.3 } } else { Material { roughness: 0.75, metallic: 0.0 } };
            let handle = renderer.upload_mesh_with(&mesh, material)?;
            out.meshes.push((link, handle, id));
            if cfg.config.randomization.robot_materials.is_some() {
                out.materials.push((handle, mesh.texture.clone(), material));
            }
            let name = &r.robot.model.links[link].name;
            out.glbs.push(SceneModel { id: format!("robot/{name}"), frame_id: name.clone(), glb: glb_of(&mesh) });
        }
    }
    Ok(out)
}

/// Everything a worker needs to turn sample coordinates into a sample.
pub struct SampleFactory<'a> {
    pub config: &'a Config,
    pub objects: &'a [LoadedObject],
    renderer: Box<dyn Renderer + 'a>,
    uploaded: Uploaded,
    held: HeldLooks,
    /// The robot and the trajectory it is recording (with a robot).
    trajectories: Option<TrajectoryCache>,
    /// Time spent per stage, for `vtgen bench`.
    pub times: StageTimes,
}

/// What a worker uploads and derives once, at its start, and only reads afterwards.
struct Uploaded {
    object_meshes: Vec<MeshHandle>,
    floor: MeshHandle,
    backdrop: MeshHandle,
    /// Images for the `image` texture kind of the randomizer.
    images: ImageLibrary,
    /// (link, mesh, mask id) of every drawn robot link.
    robot_meshes: Vec<(usize, MeshHandle, u8)>,
    /// Every drawn robot link's own texture and material, for `randomization.robot_materials`
    /// (the randomized look is set per sample, the canonical samples get these back).
    robot_materials: Vec<(MeshHandle, vt_objects::Texture, Material)>,
    /// The meshes shards carry for Foxglove's 3D view: per object, and the drawn robot links.
    object_glbs: Vec<std::sync::Arc<Vec<u8>>>,
    robot_glbs: Vec<SceneModel>,
    /// Per object: the model points the occlusion level is measured with.
    model_points: Vec<Vec<glam::DVec3>>,
}

/// What the renderer holds now, so that what a sample leaves unchanged is not made or uploaded
/// again.
#[derive(Default)]
struct HeldLooks {
    floor_texture: TextureSlot,
    backdrop_texture: TextureSlot,
    /// The robot look the renderer holds now (None: not set yet), so an unchanged one (a run of
    /// canonical samples) is not uploaded again.
    robot_look: Option<Option<vt_randomizers::RobotLook>>,
}

/// The robot and its last simulated trajectory: simulated when its first sample is made, then
/// read by the samples that follow.
struct TrajectoryCache {
    robot: RobotScene,
    touch: TouchStep,
    recording: Option<Recording>,
}

/// What a shard's samples add up to: the figures its `vtgen.shard` record carries. The shard's
/// writer owns it; [`SampleFactory::make`] adds each sample.
#[derive(Debug, Clone, Default)]
pub struct ShardTally {
    /// Samples per occlusion bin ([`OcclusionBin::ALL`] order).
    pub occlusion: [u64; 3],
    /// The grasp loop's figures of the trajectories that start in the shard.
    pub grasp: GraspStats,
}

/// Accumulated time of each stage of making samples.
#[derive(Debug, Clone, Copy, Default)]
pub struct StageTimes {
    /// Grasp-loop simulation (whole trajectories, when their first sample is made).
    pub physics: Duration,
    pub main_render: Duration,
    /// The pads' depth views (one submission).
    pub tactile_render: Duration,
    /// Contact pixels to tactile points.
    pub tactile_extract: Duration,
    /// The optical tactile images (and reference images when a sensor changed): wall and the
    /// worker thread's CPU time.
    pub tactile_optical: Duration,
    pub tactile_optical_cpu: Duration,
    /// Optical tactile images made.
    pub optical_images: u64,
    /// The pads' force fields (`robot.tactile.force_field`) and how many were made.
    pub tactile_forces: Duration,
    pub force_fields: u64,
    /// Occlusion level (model points against the depth cloud); the object's unoccluded
    /// silhouette comes with the main render.
    pub occlusion: Duration,
    /// Physics steps taken (trajectories simulated, failed attempts and redone moves included).
    pub physics_steps: u64,
    /// The worker thread's CPU time: in the grasp loop, inside the renderer's calls (submission,
    /// and the rasterization when lavapipe runs it on the calling thread), and in everything else
    /// of the sample path (scene and textures, touch, occlusion, assembly).
    pub physics_cpu: Duration,
    pub render_call_cpu: Duration,
    pub other_cpu: Duration,
}

impl StageTimes {
    /// A touch reading's times, into their stages.
    fn add_touch(&mut self, t: &crate::sensors::touch::TouchTimes) {
        self.render_call_cpu += t.render_call_cpu;
        self.tactile_render += t.render;
        self.tactile_extract += t.extract;
        self.tactile_forces += t.forces;
        self.force_fields += t.force_fields;
        self.tactile_optical += t.optical;
        self.tactile_optical_cpu += t.optical_cpu;
        self.optical_images += t.optical_images;
    }
}

impl std::ops::AddAssign<&StageTimes> for StageTimes {
    fn add_assign(&mut self, o: &StageTimes) {
        // Destructured, so that a new field is a compile error here until it is added up.
        let StageTimes {
            physics,
            main_render,
            tactile_render,
            tactile_extract,
            tactile_optical,
            tactile_optical_cpu,
            optical_images,
            tactile_forces,
            force_fields,
            occlusion,
            physics_steps,
            physics_cpu,
            render_call_cpu,
            other_cpu,
        } = o;
        self.physics += *physics;
        self.main_render += *main_render;
        self.tactile_render += *tactile_render;
        self.tactile_extract += *tactile_extract;
        self.tactile_optical += *tactile_optical;
        self.tactile_optical_cpu += *tactile_optical_cpu;
        self.optical_images += *optical_images;
        self.tactile_forces += *tactile_forces;
        self.force_fields += *force_fields;
        self.occlusion += *occlusion;
        self.physics_steps += *physics_steps;
        self.physics_cpu += *physics_cpu;
        self.render_call_cpu += *render_call_cpu;
        self.other_cpu += *other_cpu;
    }
}

/// A simulated trajectory and its grasp-loop figures.
struct Recording {
    /// (object index, trajectory)
    key: (u32, u32),
    trajectory: Trajectory,
    stats: GraspStats,
}

/// The robot as the physics stage left it for one sample: its info, the pads (world) and
/// the frames `/tf` carries.
struct PosedRobot {
    info: RobotInfo,
    /// The links touching the object (the robot's touch links in contact).
    links_in_contact: Vec<usize>,
    pads: Vec<DAffine3>,
    transforms: Vec<(String, String, Pose)>,
    t_world_object: DAffine3,
    t_world_palm: DAffine3,
    /// The physics' contacts and forces (palm frame), where the backend gives them.
    hand_contacts: Option<Vec<crate::physics::HandContact>>,
}

/// Which recorded state of the trajectory a sample shows: an instance (snapshots) or a physics
/// step of the episode (`Trajectory::steps`).
#[derive(Debug, Clone, Copy)]
enum StateAt {
    Instance(u32),
    Step(u64),
}

impl<'a> SampleFactory<'a> {
    /// A worker's factory: the objects and the robot uploaded to its renderer once.
    // The uploads in the order the renderer hands out their handles: floor, backdrop, objects,
    // robot links.
    pub fn new(cfg: &'a LoadedConfig, objects: &'a [LoadedObject], mut renderer: Box<dyn Renderer + 'a>) -> Result<Self> {
        let config = &cfg.config;
        let floor = renderer.upload_mesh_with(&floor_mesh(), Material { roughness: 0.85, metallic: 0.0 })?;
        let backdrop = renderer.upload_mesh_with(&backdrop_mesh(config), Material { roughness: 0.95, metallic: 0.0 })?;
        let object_meshes = objects
            .iter()
            .map(|o| {
                let material = Material { roughness: o.surface.roughness, metallic: o.surface.metallic };
                renderer.upload_mesh_with(&o.mesh, material).with_context(|| format!("uploading '{}'", o.id))
            })
            .collect::<Result<_>>()?;
        let rnd = &config.randomization;
        // Photos for the `image` texture kind: loaded once, resized, shared by every sample.
        let images = if rnd.enabled {
            ImageLibrary::for_config(rnd, &cfg.base_dir).map_err(|e| anyhow::anyhow!("{}: randomization: {e}", cfg.path.display()))?
        } else {
            ImageLibrary::empty()
        };
        let robot = config.robot.as_ref().map(|r| RobotScene::new(cfg, r, objects)).transpose()?;
        let drawn = match &robot {
            Some(r) => upload_robot(renderer.as_mut(), cfg, r)?,
            None => DrawnRobot::default(),
        };
        let DrawnRobot { meshes: robot_meshes, materials: robot_materials, glbs: robot_glbs } = drawn;
        let object_glbs = objects.iter().map(|o| glb_of(&o.mesh)).collect();
        let touch = match &robot {
            Some(r) => {
                Some(TouchStep::new(&r.robot, &r.config.tactile, r.config.physics.friction, &cfg.pad_sensors, r.hand_meshes.as_ref())?)
            }
            None => None,
        };
        let model_points = objects.iter().map(|o| model_points(&o.mesh, config.scene.occlusion_points as usize)).collect();
        Ok(SampleFactory {
            config,
            objects,
            renderer,
            uploaded: Uploaded {
                object_meshes,
                floor,
                backdrop,
                images,
                robot_meshes,
                robot_materials,
                object_glbs,
                robot_glbs,
                model_points,
            },
            held: HeldLooks::default(),
            trajectories: robot.zip(touch).map(|(robot, touch)| TrajectoryCache { robot, touch, recording: None }),
            times: StageTimes::default(),
        })
    }

    /// Time the renderer spent copying images out of readback buffers so far.
    pub fn readback_time(&self) -> Duration {
        self.renderer.readback_time()
    }

    /// Times the renderer's passes one by one from now on (`vtgen bench --per-pass`); false when
    /// it has none to time.
    pub fn time_render_passes(&mut self) -> bool {
        self.renderer.time_passes()
    }

    /// The renderer's pass times since `time_render_passes`.
    pub fn render_pass_times(&self) -> Option<crate::render::PassTimes> {
        self.renderer.pass_times()
    }

    pub fn renderer_name(&self) -> String {
        self.renderer.describe()
    }

    pub fn has_robot(&self) -> bool {
        self.trajectories.is_some()
    }

    /// What `/scene/models` shows while `object_index` is the target: its mesh in the `object`
    /// frame and the robot links in theirs.
    pub fn scene_models(&self, object_index: u32) -> Vec<SceneModel> {
        let obj = &self.objects[object_index as usize];
        let mut models = vec![SceneModel {
            id: format!("object/{}", obj.id),
            frame_id: frames::OBJECT.into(),
            glb: self.uploaded.object_glbs[object_index as usize].clone(),
        }];
        models.extend(self.uploaded.robot_glbs.iter().cloned());
        models
    }

    /// One sample, stage by stage: scene (camera, look) -> physics (the grasp's recorded instance
    /// poses the object and the robot) -> draw list -> main render (+ RGB-D noise) -> touch ->
    /// occlusion -> the assembled sample and its `/sample/info`. Counts the worker thread's CPU
    /// time per part (`StageTimes`).
    pub fn make(&mut self, split: Split, index: u64, r: &SampleRef, tally: &mut ShardTally) -> Result<Sample> {
        let clock = StageClock::start();
        let (physics0, render0) = (self.times.physics_cpu, self.times.render_call_cpu);
        let sample = self.make_sample(split, index, r);
        let inside = (self.times.physics_cpu - physics0) + (self.times.render_call_cpu - render0);
        self.times.other_cpu += clock.cpu().saturating_sub(inside);
        let sample = sample?;
        if let Some(bin) = sample.info.occlusion.and_then(|o| OcclusionBin::of(o.level)) {
            tally.occlusion[bin.index()] += 1;
        }
        // A trajectory's figures count in the shard where it starts, whichever worker made it.
        if let Some(TrajectoryCache { recording: Some(rec), .. }) = &self.trajectories
            && r.instance == 0
        {
            tally.grasp.merge(&rec.stats);
        }
        Ok(sample)
    }

    /// The stages of `make`.
    fn make_sample(&mut self, split: Split, index: u64, r: &SampleRef) -> Result<Sample> {
        let objects = self.objects;
        let obj = &objects[r.object_index as usize];
        let key = SampleKey { seed: self.config.seed, object_id: &obj.id, trajectory: r.trajectory, instance: r.instance };
        // An episode is one scene, one look and one sensor unit per pad (its frame 0's), with
        // each frame's own sensor noise.
        let timeline = EpisodeTimeline::of(self.config);
        let scene_key = SampleKey { instance: if timeline.is_some() { 0 } else { r.instance }, ..key };
        let at = timeline.map_or(StateAt::Instance(r.instance), |t| StateAt::Step(r.instance as u64 * t.periods.camera));
        let mut scene = self.sample_scene(&scene_key)?;
        let mut draws = [self.uploaded.floor, self.uploaded.backdrop]
            .map(|mesh| Draw { mesh, t_world_model: DMat4::IDENTITY, mask_id: mask_ids::BACKGROUND, role: DrawRole::Environment })
            .to_vec();
        let mut posed = if self.has_robot() { Some(self.pose_robot(r, &obj.id, at, &mut draws)?) } else { None };
        if let Some(p) = &posed {
            scene.t_world_object = pose_of(&p.t_world_object);
        }
        let distractors = place_distractors(self.objects, &scene, r.object_index as usize);
        let object_draw = self.add_object_draws(&scene, r.object_index as usize, &distractors, &mut draws);
        let (mut img, depth_noisy) = self.render_main(&scene, &key, &draws)?;
        let tactile = match posed.as_mut() {
            Some(p) => Some(self.sense_touch(&scene, (&scene_key, &key), "", object_draw, p)?),
            None => None,
        };
        let t_camera_object = scene.t_world_camera.inverse().compose(&scene.t_world_object);
        let visible_pixels = img.mask.iter().filter(|&&m| m == mask_ids::TARGET_OBJECT).count();
        let occlusion = self.annotate_occlusion(r.object_index as usize, &t_camera_object, &img, visible_pixels);
        // The stored depth on its grid (`output.depth_grid`), after the annotations read the exact one.
        // The noisy reading keeps its own sensor's quantization (a grid would only add entropy).
        if let Some(bits) = self.config.output.depth_grid.bits(self.config.sampling.record.is_some()) {
            snap_depth_to_grid(&mut img.depth, bits);
        }
        let k = self.config.camera.k();
        let (robot_info, extra_transforms) = posed.map_or((None, Vec::new()), |p| (Some(p.info), p.transforms));
        let info = SampleInfo {
            split,
            index,
            object_id: obj.id.clone(),
            object_index: obj.index,
            mask_id: mask_ids::TARGET_OBJECT,
            trajectory: r.trajectory,
            instance: r.instance,
            randomized: scene.appearance.randomized,
            appearance: serde_json::to_value(scene.appearance.info())?,
            distractors: distractors
                .iter()
                .map(|d| PlacedDistractor { object_id: objects[d.object].id.clone(), mask_id: d.mask_id, t_world_distractor: d.pose })
                .collect(),
            visible_pixels: visible_pixels as u64,
            occlusion: Some(occlusion),
            t_world_camera: scene.t_world_camera,
            t_camera_object,
            robot: robot_info,
            episode: timeline.map(|t| self.episode_frame(r, &t)),
        };
        let episode = match &timeline {
            Some(t) => Some(self.episode_streams(r, &obj.id, &scene, (&scene_key, &key), t)?),
            None => None,
        };
        Ok(Sample {
            index,
            width: img.width,
            height: img.height,
            rgb: img.rgb,
            depth: img.depth,
            depth_noisy,
            mask: img.mask,
            k: [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
            t_camera_object,
            t_world_camera: scene.t_world_camera,
            t_world_object: scene.t_world_object,
            extra_transforms,
            info,
            tactile,
            episode,
        })
    }

    /// Where frame `r.instance` of an episode stands: its time and the arm move it shows (0 up to
    /// the settled grasp).
    fn episode_frame(&self, r: &SampleRef, t: &EpisodeTimeline) -> EpisodeFrameInfo {
        let step = r.instance as u64 * t.periods.camera;
        let per_move = ((t.steps - t.grasp_steps) / self.config.sampling.instances_per_trajectory as u64).max(1);
        let since_settled = step.saturating_sub(t.grasp_steps);
        EpisodeFrameInfo {
            frame: r.instance,
            time_s: step as f64 * t.timestep,
            arm_move: (since_settled.max(1) - 1).div_euclid(per_move) as u32,
            settled_s: t.settled_s(),
        }
    }

    /// Adds the distractors' draws and the target object's to `draws`; the object's draw.
    fn add_object_draws(&self, scene: &SampledScene, object: usize, distractors: &[Distractor], draws: &mut Vec<Draw>) -> Draw {
        let meshes = &self.uploaded.object_meshes;
        draws.extend(distractors.iter().map(|d| Draw {
            mesh: meshes[d.object],
            t_world_model: d.pose.matrix(),
            mask_id: d.mask_id,
            role: DrawRole::Occluder,
        }));
        let object_draw = Draw {
            mesh: meshes[object],
            t_world_model: scene.t_world_object.matrix(),
            mask_id: mask_ids::TARGET_OBJECT,
            role: DrawRole::Target,
        };
        draws.push(object_draw);
        object_draw
    }

    /// The scene stage: camera, look and candidate distractors from the sample's key, with the
    /// floor's and backdrop's textures set in the renderer.
    fn sample_scene(&mut self, key: &SampleKey) -> Result<crate::scene::SampledScene> {
        let ws = &self.config.scene.workspace;
        let workspace_center = glam::DVec3::from_array(std::array::from_fn(|k| 0.5 * (ws.min[k] + ws.max[k])));
        let ctx = AppearanceContext {
            workspace_center,
            workspace_half_extent: [0.3, 0.2],
            distractor_candidates: self.objects.len() - 1,
            images: &self.uploaded.images,
        };
        let scene = sample_scene(self.config, key, &ctx);
        let a = &scene.appearance;
        self.held.floor_texture.set(self.renderer.as_mut(), self.uploaded.floor, &a.floor, a.floor_tile)?;
        self.held.backdrop_texture.set(self.renderer.as_mut(), self.uploaded.backdrop, &a.backdrop, a.backdrop_tile)?;
        // The robot's look: randomized, or its own (empty unless `robot_materials` is configured).
        if self.held.robot_look != Some(a.robot) {
            for (mesh, texture, material) in &self.uploaded.robot_materials {
                match a.robot {
                    Some(look) => {
                        self.renderer.set_texture(*mesh, &tinted(texture, look.tint), 1.0)?;
                        self.renderer.set_material(*mesh, Material { roughness: look.roughness, metallic: look.metallic })?;
                    }
                    None => {
                        self.renderer.set_texture(*mesh, texture, 1.0)?;
                        self.renderer.set_material(*mesh, *material)?;
                    }
                }
            }
            self.held.robot_look = Some(a.robot);
        }
        Ok(scene)
    }

    /// The physics stage: the grasp loop's recorded instance (the trajectory is simulated when its
    /// first sample is made) poses the object and the robot; the robot's links join the draw list.
    fn pose_robot(&mut self, r: &SampleRef, object_id: &str, at: StateAt, draws: &mut Vec<Draw>) -> Result<PosedRobot> {
        let TrajectoryCache { robot, recording, .. } = self.trajectories.as_mut().expect("called with a robot");
        let instances = self.config.sampling.instances_per_trajectory;
        let key = (r.object_index, r.trajectory);
        if recording.as_ref().map(|rec| rec.key) != Some(key) {
            let (clock, steps0) = (StageClock::start(), robot.physics_steps());
            let sim = robot.simulate(self.config.seed, r.object_index, object_id, r.trajectory, instances);
            self.times.physics += clock.wall();
            self.times.physics_cpu += clock.cpu();
            self.times.physics_steps += robot.physics_steps() - steps0;
            *recording = Some(Recording { key, trajectory: sim.trajectory?, stats: sim.stats });
        }
        let rec = recording.as_ref().expect("set above");
        let attempts = rec.trajectory.attempts;
        let (st, grasp) = match at {
            StateAt::Instance(i) => {
                let regrasps = robot.config.grasp.regrasp_on_loss;
                (&rec.trajectory.instances[i as usize], regrasps.then(|| rec.trajectory.instance_grasps[i as usize]))
            }
            StateAt::Step(k) => (&rec.trajectory.steps[k as usize], None),
        };
        let t_world_palm = robot.t_world_base * st.t_base_palm;
        let posed = pose_links(&robot.robot, robot.t_world_base, t_world_palm, &st.q, self.uploaded.robot_meshes.iter().map(|m| m.0));
        for (&(_, mesh, id), (_, t_world_link)) in self.uploaded.robot_meshes.iter().zip(&posed.links) {
            draws.push(Draw { mesh, t_world_model: DMat4::from(*t_world_link), mask_id: id, role: DrawRole::Occluder });
        }
        let model = &robot.robot.model;
        let links_in_contact: Vec<usize> =
            robot.robot.touch_links.iter().zip(&st.contacts).filter(|(_, c)| c.is_some()).map(|(&link, _)| link).collect();
        let info = RobotInfo {
            physics_backend: robot.backend_name().into(),
            links_in_contact: links_in_contact.iter().map(|&l| model.links[l].name.clone()).collect(),
            slip_mm: st.slip_translation * 1e3,
            slip_deg: st.slip_rotation.to_degrees(),
            penetration_mm: st.penetration * 1e3,
            grasp_attempts: attempts,
            grasp,
            turn_target_deg: rec.trajectory.turn_target_deg,
            joint_positions: robot.robot.model.dof_names().iter().zip(&st.q).map(|(n, v)| (n.to_string(), *v)).collect(),
            t_world_palm: pose_of(&t_world_palm),
            tactile: None,
        };
        Ok(PosedRobot {
            info,
            links_in_contact,
            pads: posed.pads,
            transforms: posed.transforms,
            t_world_object: t_world_palm * st.t_palm_object,
            t_world_palm,
            hand_contacts: st.hand_contacts.clone(),
        })
    }

    /// An episode frame's faster streams: the touch at the tactile rate after the frame and the
    /// state from the frame on, up to the next frame (the last frame: its own state only).
    fn episode_streams(
        &mut self,
        r: &SampleRef,
        object_id: &str,
        scene: &crate::scene::SampledScene,
        keys: (&SampleKey, &SampleKey),
        timeline: &EpisodeTimeline,
    ) -> Result<EpisodeData> {
        let p = timeline.periods;
        let step0 = r.instance as u64 * p.camera;
        let end = (step0 + p.camera).min(timeline.steps + 1);
        let mut tactile = Vec::new();
        for step in (step0 + p.tactile..end).step_by(p.tactile as usize) {
            let mut posed = self.pose_robot(r, object_id, StateAt::Step(step), &mut Vec::new())?;
            let object = Draw {
                mesh: self.uploaded.object_meshes[r.object_index as usize],
                t_world_model: DMat4::from(posed.t_world_object),
                mask_id: mask_ids::TARGET_OBJECT,
                role: DrawRole::Target,
            };
            let touch = self.sense_touch(scene, keys, &format!("@{step}"), object, &mut posed)?;
            tactile.push((timeline.time_ns(step), touch));
        }
        let states =
            (step0..end).step_by(p.state as usize).map(|step| (timeline.time_ns(step), self.state_record(step, scene, timeline))).collect();
        Ok(EpisodeData { time_ns: timeline.time_ns(step0), tactile, states })
    }

    /// The episode's state at physics step `step`: joints, the object's pose and its twist since
    /// the step before.
    fn state_record(&self, step: u64, scene: &crate::scene::SampledScene, timeline: &EpisodeTimeline) -> StateRecord {
        let TrajectoryCache { robot, recording, .. } = self.trajectories.as_ref().expect("episodes have a robot");
        let steps = &recording.as_ref().expect("simulated by the frame").trajectory.steps;
        let st = &steps[step as usize];
        let world = |s: &crate::physics::grasp::InstanceState| robot.t_world_base * s.t_base_palm * s.t_palm_object;
        let now = world(st);
        let (linear, angular) = match step.checked_sub(1) {
            None => (glam::DVec3::ZERO, glam::DVec3::ZERO),
            Some(before) => {
                let prev = world(&steps[before as usize]);
                let dt = timeline.timestep;
                let turn = glam::DQuat::from_mat3(&now.matrix3) * glam::DQuat::from_mat3(&prev.matrix3).inverse();
                ((now.translation - prev.translation) / dt, turn.to_scaled_axis() / dt)
            }
        };
        let touch_names = robot.robot.touch_link_names();
        StateRecord {
            time_s: step as f64 * timeline.timestep,
            joint_positions: robot.robot.model.dof_names().iter().zip(&st.q).map(|(n, v)| (n.to_string(), *v)).collect(),
            t_world_object: pose_of(&now),
            // As the frame's own `T_camera_object` is made, so the two agree to the last bit.
            t_camera_object: scene.t_world_camera.inverse().compose(&pose_of(&now)),
            t_world_palm: pose_of(&(robot.t_world_base * st.t_base_palm)),
            linear_velocity: linear.to_array(),
            angular_velocity: angular.to_array(),
            links_in_contact: touch_names.iter().zip(&st.contacts).filter(|(_, c)| c.is_some()).map(|(n, _)| n.clone()).collect(),
        }
    }

    /// The render stage: the main camera's colour, depth and mask, and the noisy RGB-D reading
    /// (on copies: the clean depth stays the ground truth).
    fn render_main(
        &mut self,
        scene: &crate::scene::SampledScene,
        key: &SampleKey,
        draws: &[Draw],
    ) -> Result<(crate::render::RenderOutput, Option<Vec<f32>>)> {
        let view = View::of_camera(&self.config.camera, scene.t_world_camera.matrix());
        let light = &scene.appearance.light;
        let lighting = Lighting {
            light_position: light.position,
            light_target: light.target,
            light_color: light.color.map(|c| c * light.intensity),
            cone_deg: light.cone_deg,
            softness: light.softness,
            ambient: scene.appearance.ambient,
            background: self.config.scene.background,
            shadows: true,
        };
        let clock = StageClock::start();
        let mut img = self.renderer.render(&view, &lighting, draws)?;
        self.times.main_render += clock.wall();
        self.times.render_call_cpu += clock.cpu();
        let noise = &self.config.camera.noise;
        let mut noise_rng = SampleStream::sample(key, "sensor_noise");
        let k = view.k;
        let depth_noisy =
            noise.depth.as_ref().map(|d| d.apply(&img.depth, img.width, img.height, [k.fx, k.fy, k.cx, k.cy], &mut noise_rng));
        if let Some(c) = &noise.color {
            c.apply(&mut img.rgb, &mut noise_rng);
        }
        Ok((img, depth_noisy))
    }

    /// The touch stage (`sensors::touch`): the posed pads and the physics' contacts in, the
    /// touch out; what it says of itself goes into the robot's info.
    /// `keys`: the sample's scene key (its sensor units) and its own key (its sensor noise, with
    /// `noise_tag` appended to the streams' names: the episode's touch between frames).
    fn sense_touch(
        &mut self,
        scene: &crate::scene::SampledScene,
        (unit_key, key): (&SampleKey, &SampleKey),
        noise_tag: &str,
        object: Draw,
        posed: &mut PosedRobot,
    ) -> Result<TactileData> {
        let touch = &mut self.trajectories.as_mut().expect("called with a robot").touch;
        let input = TouchInput {
            t_world_pads: &posed.pads,
            links_in_contact: &posed.links_in_contact,
            t_world_palm: posed.t_world_palm,
            hand_contacts: posed.hand_contacts.as_deref(),
            object,
            t_camera_world: DAffine3::from_mat4(scene.t_world_camera.inverse().matrix()),
            unit_key,
            key,
            noise_tag,
            // Sensor-to-sensor variation: per pad, in the randomized samples only.
            variation: self.config.randomization.tactile_sensors.as_ref().filter(|_| scene.appearance.randomized),
            // Episodes write the reference images once, with their first frame.
            write_reference: self.config.sampling.record.is_none() || (key.instance == 0 && noise_tag.is_empty()),
        };
        let reading = touch.sense(self.renderer.as_mut(), &input)?;
        self.times.add_touch(&reading.times);
        posed.info.tactile = Some(reading.info);
        Ok(reading.data)
    }

    /// The annotate stage: the paper's occlusion level (model points vs the depth cloud) and the
    /// visible share (`visible_pixels` of the mask) of the object's silhouette.
    fn annotate_occlusion(
        &mut self,
        object_index: usize,
        t_camera_object: &Pose,
        img: &crate::render::RenderOutput,
        visible_pixels: usize,
    ) -> OcclusionInfo {
        let k = self.config.camera.k();
        let pts: Vec<glam::DVec3> = self.uploaded.model_points[object_index].iter().map(|p| t_camera_object.transform_point(*p)).collect();
        let eps = self.config.scene.occlusion_epsilon_mm * 1e-3;
        let clock = StageClock::start();
        let (level, visible_points) = occlusion_level(&pts, &img.depth, img.width, img.height, &k, eps);
        self.times.occlusion += clock.wall();
        let alone = img.silhouette_pixels;
        OcclusionInfo {
            level,
            visible_points: visible_points as u64,
            model_points: pts.len() as u64,
            epsilon_mm: self.config.scene.occlusion_epsilon_mm,
            silhouette_pixels: alone as u64,
            silhouette_visible_fraction: if alone > 0 { visible_pixels as f64 / alone as f64 } else { 0.0 },
        }
    }
}
