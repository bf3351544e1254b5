//! The touch step: the posed pads and the physics' contacts in, the sample's touch out (pad
//! depth views, the tactile point cloud, the optical pads' images, the force fields) with what
//! `/sample/info` says of it. Each pad's sensor comes from the config's rules
//! (`TactileConfig::pad_sensors`); the kinds' own rules are in `sensors::tactile::SensorKind`.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use anyhow::{Context, Result};
use glam::{DAffine3, DVec3};
use vt_dataset::{OpticalPadImage, PadForceField, PadForceInfo, PadMarkerFlow, TactileData, TactilePointRecord, TouchInfo};
use vt_objects::TexturedMesh;
use vt_randomizers::{SampleKey, SampleStream, TactileSensorRandomization, sample_sensor_variation};
use vt_robot::Robot;

use super::force_field::{self, GelShear};
use super::optical::{optical_image_shaded, optical_image_with_flow, reference_image, varied};
use super::tactile::{FingerSurface, PadView, TactileReading, finger_surface, gap_above_surface, sense};
use crate::config::{OpticalSensor, PadSensor, TactileConfig};
use crate::cpu_clock::StageClock;
use crate::physics::HandContact;
use crate::render::{Draw, Renderer};

/// A worker's touch step: the robot's pads with their sensors and sizes, the real fingers'
/// surface under them (with the robot meshes), and each optical pad's last reference image.
pub struct TouchStep {
    config: TactileConfig,
    /// The friction coefficient of the force fields' slip rule (the physics').
    friction: f64,
    pads: Vec<TouchPad>,
    finger_surface: Option<FingerSurface>,
    /// Per pad: the last optical sensor's reference image, reused while the sensor stays the same.
    references: Vec<Option<(OpticalSensor, Vec<u8>)>>,
}

/// A pad as the touch step knows it.
struct TouchPad {
    name: String,
    link: usize,
    /// Sensing area (length, width; m).
    size: (f64, f64),
    sensor: PadSensor,
}

/// What one touch reading takes: where the pads are and what touches them.
pub struct TouchInput<'a> {
    /// Each pad's pose (world), `Robot::pads` order.
    pub t_world_pads: &'a [DAffine3],
    /// The robot's links touching the object.
    pub links_in_contact: &'a [usize],
    pub t_world_palm: DAffine3,
    /// The physics' contacts and forces (palm frame), where the backend gives them.
    pub hand_contacts: Option<&'a [HandContact]>,
    /// The object, drawn alone in the pads' views.
    pub object: Draw,
    /// The frame the points are given in (the main camera's).
    pub t_camera_world: DAffine3,
    /// The sample's sensor units (`unit_key`) and its own noise (`key`, with `noise_tag` appended
    /// to the streams' names: the episode's touch between frames).
    pub unit_key: &'a SampleKey<'a>,
    pub key: &'a SampleKey<'a>,
    pub noise_tag: &'a str,
    /// Sensor-to-sensor variation of the optical pads (the randomized samples only).
    pub variation: Option<&'a TactileSensorRandomization>,
    /// Whether the optical pads' reference images go with this reading.
    pub write_reference: bool,
}

/// One touch reading: the data, what `/sample/info` says of it, and the time it took.
pub struct Touch {
    pub data: TactileData,
    pub info: TouchInfo,
    pub times: TouchTimes,
}

/// Time per part of a touch reading (`vtgen bench`'s stages).
#[derive(Debug, Clone, Copy, Default)]
pub struct TouchTimes {
    /// The pads' depth views (one submission), and the extraction of the points after it.
    pub render: Duration,
    pub extract: Duration,
    /// The worker thread's CPU time in the renderer's call and the extraction.
    pub render_call_cpu: Duration,
    pub forces: Duration,
    pub force_fields: u64,
    pub optical: Duration,
    pub optical_cpu: Duration,
    pub optical_images: u64,
}

/// The pads' force fields of one reading, the forces each was made from, and the whole hand's
/// force (world, N).
struct ForceReadings {
    fields: Vec<PadForceField>,
    info: BTreeMap<String, PadForceInfo>,
    hand_force_n: [f64; 3],
}

impl TouchStep {
    /// The touch step of `robot` with `sensors` (`LoadedConfig::pad_sensors`); `hand_meshes`:
    /// the real meshes of the links (with the robot meshes), whose surface under each pad the
    /// contact rule measures from.
    pub fn new(
        robot: &Robot,
        config: &TactileConfig,
        friction: f64,
        sensors: &[PadSensor],
        hand_meshes: Option<&HashMap<usize, TexturedMesh>>,
    ) -> Result<Self> {
        let pads: Vec<TouchPad> = robot
            .pads
            .iter()
            .zip(robot.pad_sizes())
            .zip(sensors)
            .map(|((pad, size), sensor)| TouchPad { name: pad.name.clone(), link: pad.link, size, sensor: sensor.clone() })
            .collect();
        let finger_surface = match hand_meshes {
            Some(hand) => Some(finger_surfaces(robot, &pads, hand, config.resolution)?),
            None => None,
        };
        Ok(TouchStep { config: config.clone(), friction, pads, finger_surface, references: Vec::new() })
    }

    /// Each pad's sensing area (length, width; m), `Robot::pads` order.
    pub fn pad_sizes(&self) -> Vec<(f64, f64)> {
        self.pads.iter().map(|p| p.size).collect()
    }

    /// One reading: the pad views of the object alone and the tactile point cloud (in the frame
    /// `t_camera_world` maps to), the optical pads' images, the force fields when configured.
    pub fn sense(&mut self, renderer: &mut dyn Renderer, input: &TouchInput) -> Result<Touch> {
        let cfg = &self.config;
        let mut times = TouchTimes::default();
        let clock = StageClock::start();
        // A pad feels the object when its link touches it (FORMAT.md, "Touch and contact").
        let views: Vec<PadView> = self
            .pads
            .iter()
            .zip(input.t_world_pads)
            .map(|(pad, &t_world_pad)| {
                let mut sensor = pad.sensor.clone();
                if let (Some(s), Some(v)) = (&sensor.optical, input.variation) {
                    sensor.optical = Some(varied(s, &sample_sensor_variation(v, input.unit_key, &pad.name, s.lights.len())));
                }
                PadView { size: pad.size, sensor, t_world_pad, touching: input.links_in_contact.contains(&pad.link) }
            })
            .collect();
        let reading = sense(renderer, cfg, &views, self.finger_surface.as_ref(), input.object, &input.t_camera_world)?;
        // The extraction (hundredths of a millisecond) is counted with the renderer's call.
        times.render_call_cpu = clock.cpu();
        times.render = reading.render_time;
        times.extract = clock.wall() - reading.render_time;
        let clock = StageClock::start();
        let forces = match cfg.force_field {
            Some(field) => Some(self.force_fields(field.resolution, &views, &reading.depth, input)?),
            None => None,
        };
        times.forces = clock.wall();
        times.force_fields = forces.as_ref().map_or(0, |f| f.fields.len() as u64);
        // With force fields, the optical pads' markers move with their gel's shear displacement.
        let shears: Option<Vec<Option<GelShear>>> = match (&forces, cfg.force_field) {
            (Some(f), Some(field)) => Some(
                f.fields
                    .iter()
                    .zip(&views)
                    .map(|(f, pad)| pad.optical().map(|_| GelShear::new(f, pad.size, field.gel_shear_modulus_kpa * 1e3)))
                    .collect(),
            ),
            _ => None,
        };
        let clock = StageClock::start();
        let names: Vec<String> = self.pads.iter().map(|p| p.name.clone()).collect();
        let (optical, marker_flow) = optical_images(&mut self.references, input, &names, &views, (&reading, shears.as_deref()));
        times.optical = clock.wall();
        times.optical_cpu = clock.cpu();
        times.optical_images = optical.len() as u64;
        let info = self.info(&names, &views, &reading.counts, forces.as_ref())?;
        let data = TactileData {
            pads: names,
            resolution: cfg.resolution,
            depth: reading.depth,
            points: reading
                .points
                .iter()
                .map(|p| TactilePointRecord { position: p.position.as_vec3().to_array(), distance: p.distance as f32, pad: p.pad })
                .collect(),
            optical,
            forces: forces.map(|f| f.fields).unwrap_or_default(),
            marker_flow,
        };
        Ok(Touch { data, info, times })
    }

    /// What `/sample/info` says of a reading: the pads' settings, sensors and sizes, the points per
    /// pad, each optical pad's sensor in this sample, the forces.
    fn info(&self, names: &[String], views: &[PadView], counts: &[u32], forces: Option<&ForceReadings>) -> Result<TouchInfo> {
        let cfg = &self.config;
        let optical = views
            .iter()
            .zip(names)
            .filter_map(|(p, n)| p.optical().map(|s| Ok((n.clone(), serde_json::to_value(s)?))))
            .collect::<Result<BTreeMap<_, _>>>()?;
        Ok(TouchInfo {
            contact_threshold_mm: cfg.contact_threshold_mm,
            sensors: names.iter().zip(&self.pads).map(|(n, p)| (n.clone(), p.sensor.model)).collect(),
            near_mm: cfg.near_mm,
            far_mm: cfg.far_mm,
            pads: names.iter().zip(&self.pads).map(|(n, p)| (n.clone(), [p.size.0, p.size.1])).collect(),
            points: names.iter().zip(counts).map(|(n, c)| (n.clone(), *c as u64)).collect(),
            optical: (!optical.is_empty()).then_some(optical),
            forces: forces.map(|f| f.info.clone()),
            hand_force_n: forces.map(|f| f.hand_force_n),
        })
    }

    /// Every pad's force field from the physics' contacts of the posed state (its depth view
    /// spreads them), the forces each was made from, and the whole hand's force (world).
    fn force_fields(&self, resolution: u32, views: &[PadView], depth: &[Vec<f32>], input: &TouchInput) -> Result<ForceReadings> {
        let cfg = &self.config;
        // The config's check requires a backend that gives its contact forces.
        let contacts = input.hand_contacts.context("the physics backend gives no contact forces for the force fields")?;
        let surface = self.finger_surface.as_ref();
        let mut fields = Vec::new();
        let mut info = BTreeMap::new();
        for (k, (pad, view)) in self.pads.iter().zip(views).enumerate() {
            let t_palm_pad = input.t_world_palm.inverse() * view.t_world_pad;
            let (on_area, link_force) = force_field::pad_contacts(contacts, pad.link, &t_palm_pad, view.size);
            let gap = gap_above_surface(&depth[k], surface.map(|s| &s[k][..]));
            let touch = force_field::PadTouch {
                pad: &pad.name,
                contacts: &on_area,
                gap: &gap,
                n: cfg.resolution,
                threshold: cfg.contact_threshold_mm * 1e-3,
                size: view.size,
                friction: self.friction,
            };
            fields.push(force_field::force_field(&touch, resolution));
            let force: DVec3 = on_area.iter().map(|c| c.force).sum();
            let pad_info = PadForceInfo {
                force_n: force.to_array(),
                link_force_n: link_force.to_array(),
                contacts: on_area.len() as u32,
                friction: self.friction,
            };
            info.insert(pad.name.clone(), pad_info);
        }
        let hand_force = input.t_world_palm.transform_vector3(contacts.iter().map(|c| c.force).sum());
        Ok(ForceReadings { fields, info, hand_force_n: hand_force.to_array() })
    }
}

/// The optical pads' images: each from its depth view (none: the pad does not touch the
/// object) and its gel's shear displacement (with force fields), with the sample's noise
/// stream for that pad, beside its sensor's reference image (`references`: the last one made per
/// pad, reused while the sensor stays the same). With force fields, also each marked pad's marker
/// flow, the one its image shows.
fn optical_images(
    references: &mut Vec<Option<(OpticalSensor, Vec<u8>)>>,
    input: &TouchInput,
    names: &[String],
    views: &[PadView],
    (reading, shears): (&TactileReading, Option<&[Option<GelShear>]>),
) -> (Vec<OpticalPadImage>, Vec<PadMarkerFlow>) {
    references.resize(views.len(), None);
    let (mut out, mut flows) = (Vec::new(), Vec::new());
    for (k, (pad, name)) in views.iter().zip(names).enumerate() {
        let Some(sensor) = pad.optical() else { continue };
        let mut noise = SampleStream::sample(input.key, &format!("tactile_image/{name}{}", input.noise_tag));
        let shear = shears.and_then(|s| s[k].as_ref());
        let (image, flow) = match &reading.optical_shaded[k] {
            Some(gpu) => optical_image_shaded(sensor, gpu, shear, Some(&mut noise)),
            None => optical_image_with_flow(sensor, reading.optical_depth[k].as_deref(), shear, Some(&mut noise)),
        };
        if shears.is_some() && sensor.markers.is_some() {
            let f32s = |p: [f64; 2]| p.map(|v| v as f32);
            flows.push(PadMarkerFlow { pad: name.clone(), markers: flow.into_iter().map(|(r, m)| (f32s(r), f32s(m))).collect() });
        }
        let cached = &mut references[k];
        if cached.as_ref().is_none_or(|(s, _)| s != sensor) {
            *cached = Some((sensor.clone(), reference_image(sensor).rgb));
        }
        // An episode's reference goes with its first frame only: the sensor unit is the same
        // for the whole episode.
        let reference = if input.write_reference { cached.as_ref().expect("set above").1.clone() } else { Vec::new() };
        out.push(OpticalPadImage { pad: name.clone(), width: image.width, height: image.height, image: image.rgb, reference });
    }
    (out, flows)
}

/// The real fingers' surface under each pad, from its link's real mesh.
fn finger_surfaces(robot: &Robot, pads: &[TouchPad], hand: &HashMap<usize, TexturedMesh>, n: u32) -> Result<FingerSurface> {
    let m = &robot.model;
    robot
        .pads
        .iter()
        .zip(pads)
        .map(|(pad, touch)| {
            let t_link_pad = m.joints[m.links[pad.frame].parent_joint.expect("a pad frame is fixed to its link")].origin;
            let mesh = hand.get(&pad.link).with_context(|| format!("pad {}: no real mesh of its link", pad.name))?;
            finger_surface(mesh, &t_link_pad, touch.size, n).with_context(|| pad.name.clone())
        })
        .collect()
}
