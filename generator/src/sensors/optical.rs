//! Optical tactile images, as a GelSight- or DIGIT-style sensor's camera sees its gel.
//!
//! From the object's depth over the sensing area (an orthographic view from the pad, the same
//! kind as the pad depth views) to an RGB image, in four steps:
//! 1. **Indentation:** the gel's free surface lies `gel_thickness` in front of the pad plane; an
//!    object closer than that pushes it in, up to the whole thickness at the pad plane.
//! 2. **Elastic spread:** the gel pulls its surroundings along. As the published simulators do, a
//!    Gaussian smoothing of the indentation approximates it: the gel's surface is the larger of
//!    the indentation and its blur, so it still follows the object wherever the object is deeper.
//! 3. **Shading:** the camera looks at the gel's painted inner surface; LEDs behind the gel light
//!    it from known directions. Per channel c and pixel p (a Lambertian gel):
//!    `I_c = tint_c * vignetting(p) * (ambient + sum_i falloff_i(p) * color_ic * max(0, m(p) . l_i))`
//!    with `m` the inner surface normal and `l_i` the direction towards LED i. Without clipping
//!    this is linear in `m`, which is what photometric stereo inverts ([`normals_from_image`]).
//! 4. **Markers and noise:** printed dots displaced away from contacts by the gel's slope (at most
//!    `shift` gel thicknesses) and, with force fields, along the gel's shear displacement
//!    ([`GelShear`]), then
//!    Gaussian pixel noise; 8 bits per channel, linear (no gamma).
//!
//! A sensor calibrated on a real unit (`robot.tactile.optical.calibration`) replaces step 3's LED
//! model by its measured one: its background image plus the light its model adds for the gel's
//! normal at each pixel ([`crate::config::optical_calibration`]).
//!
//! The reference image is the same model with no indentation and no noise. Conventions (pixel
//! centres, frames) are in FORMAT.md, `/tactile/<pad>/image`.

use glam::{DMat3, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::force_field::GelShear;
use crate::config::{OpticalSensor, led_falloff, light_matrix};
use crate::render::{GelLight, GelShading, MAX_GEL_LIGHTS};

/// The image of one sensor: `width x height` RGB, row-major, 8 bits per channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpticalImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

/// Where pixel (u, v)'s centre lies on the sensing area, as the image position `(-1..=1, -1..=1)`
/// (x along the pad's x, y along its y), and in metres.
pub fn pixel_position(sensor: &OpticalSensor, u: u32, v: u32) -> ([f64; 2], [f64; 2]) {
    let [w, h] = sensor.image_size;
    let at = [(2.0 * u as f64 + 1.0) / w as f64 - 1.0, (2.0 * v as f64 + 1.0) / h as f64 - 1.0];
    let [ax, ay] = sensor.sensing_area_mm;
    (at, [at[0] * ax * 0.5e-3, at[1] * ay * 0.5e-3])
}

/// Pixel pitch (m) along x and y.
fn pitch(sensor: &OpticalSensor) -> (f64, f64) {
    let [w, h] = sensor.image_size;
    (sensor.sensing_area_mm[0] * 1e-3 / w as f64, sensor.sensing_area_mm[1] * 1e-3 / h as f64)
}

/// The depth (z from the pad plane, per image pixel; `+inf` off the ball) of a ball of radius `r`
/// (m) pressed `pressed` (m) into the gel at `centre` (pad frame, m): the press of a calibration
/// (`vtgen tactile calibrate`) and of the model's geometric checks.
pub fn ball_press_depth(sensor: &OpticalSensor, r: f64, pressed: f64, centre: [f64; 2]) -> Vec<f32> {
    let lowest = sensor.gel_thickness_mm * 1e-3 - pressed;
    let [w, h] = sensor.image_size;
    (0..h)
        .flat_map(|v| (0..w).map(move |u| (u, v)))
        .map(|(u, v)| {
            let (_, [x, y]) = pixel_position(sensor, u, v);
            let q = (x - centre[0]).powi(2) + (y - centre[1]).powi(2);
            if q < r * r { (lowest + r - (r * r - q).sqrt()) as f32 } else { f32::INFINITY }
        })
        .collect()
}

/// Step 1: how far the object pushes the gel in (m, `0 ..= thickness`) per pixel, from its z-depth
/// in front of the pad plane (`+inf`: no object).
pub fn indentation(sensor: &OpticalSensor, depth: &[f32]) -> Vec<f64> {
    let t = sensor.gel_thickness_mm * 1e-3;
    depth.iter().map(|&d| (t - d as f64).clamp(0.0, t)).collect()
}

/// Step 2: the gel's surface, as its indentation (m) per pixel.
pub fn gel_surface(sensor: &OpticalSensor, indentation: &[f64]) -> Vec<f64> {
    let (px, py) = pitch(sensor);
    let [w, h] = sensor.image_size.map(|s| s as usize);
    let sigma_m = sensor.elastic_spread_mm * 1e-3;
    if sigma_m <= 0.0 || indentation.iter().all(|&g| g == 0.0) {
        return indentation.to_vec();
    }
    let blurred = blur_rows(indentation, w, h, sigma_m / px);
    let blurred = transpose(&blur_rows(&transpose(&blurred, w, h), h, w, sigma_m / py), h, w);
    indentation.iter().zip(&blurred).map(|(g, b)| g.max(*b)).collect()
}

/// A Gaussian blur (σ in pixels) along each row of a `w x h` image; the edges repeat.
fn blur_rows(img: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-r..=r).map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp()).collect();
    let sum: f64 = kernel.iter().sum();
    let mut out = vec![0.0; img.len()];
    for y in 0..h {
        let row = &img[y * w..(y + 1) * w];
        if row.iter().all(|&g| g == 0.0) {
            continue;
        }
        for x in 0..w {
            let mut acc = 0.0;
            for (k, weight) in kernel.iter().enumerate() {
                let xi = (x as isize + k as isize - r).clamp(0, w as isize - 1) as usize;
                acc += weight * row[xi];
            }
            out[y * w + x] = acc / sum;
        }
    }
    out
}

fn transpose(img: &[f64], w: usize, h: usize) -> Vec<f64> {
    let mut out = vec![0.0; img.len()];
    for y in 0..h {
        for x in 0..w {
            out[x * h + y] = img[y * w + x];
        }
    }
    out
}

/// The gel surface's slopes (∂g/∂x, ∂g/∂y) per pixel: central differences, one-sided at the edges;
/// zero where the gel is not displaced (it is flat there, whatever its neighbours do).
pub fn slopes(sensor: &OpticalSensor, gel: &[f64]) -> Vec<(f64, f64)> {
    let (px, py) = pitch(sensor);
    let [w, h] = sensor.image_size.map(|s| s as usize);
    let at = |x: usize, y: usize| gel[y * w + x];
    let mut out = Vec::with_capacity(gel.len());
    for y in 0..h {
        for x in 0..w {
            if at(x, y) == 0.0 {
                out.push((0.0, 0.0));
                continue;
            }
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
            let gx = if x1 > x0 { (at(x1, y) - at(x0, y)) / ((x1 - x0) as f64 * px) } else { 0.0 };
            let gy = if y1 > y0 { (at(x, y1) - at(x, y0)) / ((y1 - y0) as f64 * py) } else { 0.0 };
            out.push((gx, gy));
        }
    }
    out
}

/// The gel's inner surface normal (towards the camera, z < 0) at slopes (gx, gy).
fn inner_normal((gx, gy): (f64, f64)) -> DVec3 {
    DVec3::new(-gx, -gy, -1.0).normalize()
}

/// Tint times vignetting: the gel's colour factor per channel at image position `at`.
fn gel_color(sensor: &OpticalSensor, at: [f64; 2]) -> [f64; 3] {
    let v = 1.0 - sensor.vignetting * 0.5 * (at[0] * at[0] + at[1] * at[1]);
    sensor.background.map(|t| t * v)
}

/// Step 3: the noise-free linear intensity (0..=1 before clipping) of every pixel, 3 per pixel.
fn shade(sensor: &OpticalSensor, slopes: Option<&[(f64, f64)]>) -> Vec<f64> {
    let [w, h] = sensor.image_size;
    if let Some((model, background)) = sensor.calibration.as_ref().and_then(|c| c.shading()) {
        // A measured unit: its background plus what its light model adds for the gel's normal.
        let mut out = background.to_vec();
        for (k, &g) in slopes.into_iter().flatten().enumerate().filter(|(_, g)| **g != (0.0, 0.0)) {
            let (u, v) = (k as u32 % w, k as u32 / w);
            let (at, _) = pixel_position(sensor, u, v);
            for (o, d) in out[3 * k..3 * k + 3].iter_mut().zip(model.delta((u, v), at, g)) {
                *o += d;
            }
        }
        return out;
    }
    let lights: Vec<(DVec3, [f64; 3])> = sensor.lights.iter().map(|l| (DVec3::from_array(l.direction).normalize(), l.color)).collect();
    let mut out = Vec::with_capacity((w * h * 3) as usize);
    for v in 0..h {
        for u in 0..w {
            let (at, _) = pixel_position(sensor, u, v);
            let m = slopes.map_or(DVec3::NEG_Z, |s| inner_normal(s[(v * w + u) as usize]));
            let mut light = [sensor.ambient; 3];
            for (l, (dir, color)) in sensor.lights.iter().zip(&lights) {
                let lit = led_falloff(l, at) * m.dot(*dir).max(0.0);
                for (c, k) in light.iter_mut().zip(color) {
                    *c += lit * k;
                }
            }
            let tint = gel_color(sensor, at);
            out.extend((0..3).map(|c| tint[c] * light[c]));
        }
    }
    out
}

/// Step 4a: paints the markers into the linear image, each where [`marker_flow`] moved it.
fn paint_markers(sensor: &OpticalSensor, img: &mut [f64], flow: &[MarkerMove]) {
    let Some(m) = sensor.markers else { return };
    let [w, h] = sensor.image_size;
    let (px, py) = pitch(sensor);
    let [ax, ay] = sensor.sensing_area_mm.map(|a| a * 1e-3);
    let r = m.radius_mm * 1e-3;
    for &(_, [cx, cy]) in flow {
        let centre = (cx, cy);
        let (u0, u1) = (((centre.0 - r + ax / 2.0) / px).floor() as i64 - 1, ((centre.0 + r + ax / 2.0) / px).ceil() as i64 + 1);
        let (v0, v1) = (((centre.1 - r + ay / 2.0) / py).floor() as i64 - 1, ((centre.1 + r + ay / 2.0) / py).ceil() as i64 + 1);
        for v in v0.max(0)..v1.min(h as i64) {
            for u in u0.max(0)..u1.min(w as i64) {
                let (_, [x, y]) = pixel_position(sensor, u as u32, v as u32);
                let dist = ((x - centre.0).powi(2) + (y - centre.1).powi(2)).sqrt();
                // Coverage of the pixel by the dot, antialiased over one pixel.
                let cover = ((r - dist) / px.min(py) + 0.5).clamp(0.0, 1.0);
                if cover > 0.0 {
                    let k = (v as usize * w as usize + u as usize) * 3;
                    for c in &mut img[k..k + 3] {
                        *c *= 1.0 - m.opacity * cover;
                    }
                }
            }
        }
    }
}

/// A marker's rest position and where it is (m, pad frame).
pub type MarkerMove = ([f64; 2], [f64; 2]);

/// Each marker's rest position and where it is (m, pad frame): moved by `-shift * thickness *
/// slope` of the gel at its rest pixel (away from a contact; the slope capped at 1: a sharp edge's
/// step is not a lateral push of the whole gel) and by the gel's shear displacement there.
pub fn marker_flow(sensor: &OpticalSensor, slopes: Option<&[(f64, f64)]>, shear: Option<&GelShear>) -> Vec<MarkerMove> {
    let Some(m) = sensor.markers else { return Vec::new() };
    let [w, h] = sensor.image_size;
    let (px, py) = pitch(sensor);
    let [ax, ay] = sensor.sensing_area_mm.map(|a| a * 1e-3);
    let t = sensor.gel_thickness_mm * 1e-3;
    marker_positions(sensor)
        .into_iter()
        .map(|[rx, ry]| {
            let (gx, gy) = slopes.map_or((0.0, 0.0), |s| {
                let u = ((rx + ax / 2.0) / px).floor().clamp(0.0, w as f64 - 1.0) as u32;
                let v = ((ry + ay / 2.0) / py).floor().clamp(0.0, h as f64 - 1.0) as u32;
                s[(v * w + u) as usize]
            });
            let scale = m.shift * t / gx.hypot(gy).max(1.0);
            let [sx, sy] = shear.map_or([0.0, 0.0], |s| s.at([rx, ry]));
            ([rx, ry], [rx - scale * gx + sx, ry - scale * gy + sy])
        })
        .collect()
}

/// The markers' rest positions (m, pad frame): a grid of the configured pitch centred on the pad,
/// every dot fully inside the sensing area.
pub fn marker_positions(sensor: &OpticalSensor) -> Vec<[f64; 2]> {
    let Some(m) = sensor.markers else { return Vec::new() };
    let [ax, ay] = sensor.sensing_area_mm.map(|a| a * 1e-3);
    let (p, r) = (m.pitch_mm * 1e-3, m.radius_mm * 1e-3);
    let count = |a: f64| ((a - 2.0 * r) / p).floor().max(-1.0) as i64 + 1;
    let (nx, ny) = (count(ax), count(ay));
    (0..ny).flat_map(|j| (0..nx).map(move |i| [(i as f64 - (nx - 1) as f64 / 2.0) * p, (j as f64 - (ny - 1) as f64 / 2.0) * p])).collect()
}

/// Step 4b: 8-bit levels, with Gaussian noise of the sensor's σ when `rng` is given.
fn quantize(sensor: &OpticalSensor, img: &[f64], rng: Option<&mut ChaCha8Rng>) -> Vec<u8> {
    let level = |x: f64| (x * 255.0).round().clamp(0.0, 255.0) as u8;
    match rng {
        Some(rng) if sensor.noise_std > 0.0 => {
            let mut out = Vec::with_capacity(img.len());
            for pair in img.chunks(2) {
                // Box–Muller, both outputs used.
                let u1: f64 = rng.random::<f64>().max(1e-300);
                let u2: f64 = rng.random();
                let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
                let radius = (-2.0 * u1.ln()).sqrt() * sensor.noise_std / 255.0;
                out.extend(pair.iter().zip([c, s]).map(|(x, n)| level(x + radius * n)));
            }
            out
        }
        _ => img.iter().map(|&x| level(x)).collect(),
    }
}

/// The slopes of the gel's surface over an object at `depth` (as [`optical_image`] takes it);
/// None where the gel is not pushed in.
pub fn gel_slopes(sensor: &OpticalSensor, depth: Option<&[f32]>) -> Option<Vec<(f64, f64)>> {
    let gel = depth.map(|d| gel_surface(sensor, &indentation(sensor, d)));
    gel.filter(|g| g.iter().any(|&x| x > 0.0)).map(|g| slopes(sensor, &g))
}

/// The sensor's image with nothing touching it, without noise.
pub fn reference_image(sensor: &OpticalSensor) -> OpticalImage {
    let mut img = shade(sensor, None);
    paint_markers(sensor, &mut img, &marker_flow(sensor, None, None));
    let [width, height] = sensor.image_size;
    OpticalImage { width, height, rgb: quantize(sensor, &img, None) }
}

/// The sensor's image of an object at `depth` (z from the pad plane per image pixel, `+inf`
/// where none; `None`: nothing touches the pad), its markers moved by the gel's shear
/// displacement (`shear`, with force fields), with noise from `rng` (`None`: noise-free).
pub fn optical_image(
    sensor: &OpticalSensor,
    depth: Option<&[f32]>,
    shear: Option<&GelShear>,
    rng: Option<&mut ChaCha8Rng>,
) -> OpticalImage {
    optical_image_with_flow(sensor, depth, shear, rng).0
}

/// The sensor's image of a gel whose surface is given (its indentation per pixel, m), as a
/// height map from another simulator gives it: shaded without the elastic spread, noise-free.
pub fn optical_image_of_surface(sensor: &OpticalSensor, gel: &[f64]) -> OpticalImage {
    let slopes = slopes(sensor, gel);
    let img = shade(sensor, Some(&slopes));
    finish(sensor, img, Some(&slopes), None, None).0
}

/// [`optical_image`], and the marker flow it painted ([`marker_flow`]).
pub fn optical_image_with_flow(
    sensor: &OpticalSensor,
    depth: Option<&[f32]>,
    shear: Option<&GelShear>,
    rng: Option<&mut ChaCha8Rng>,
) -> (OpticalImage, Vec<MarkerMove>) {
    let slopes = gel_slopes(sensor, depth);
    let img = shade(sensor, slopes.as_deref());
    finish(sensor, img, slopes.as_deref(), shear, rng)
}

/// Step 4 on a shaded image: the markers where the gel's slopes and shear move them, the noise,
/// 8 bits; with the marker flow painted.
fn finish(
    sensor: &OpticalSensor,
    mut img: Vec<f64>,
    slopes: Option<&[(f64, f64)]>,
    shear: Option<&GelShear>,
    rng: Option<&mut ChaCha8Rng>,
) -> (OpticalImage, Vec<MarkerMove>) {
    let flow = marker_flow(sensor, slopes, shear.filter(|s| !s.is_empty()));
    paint_markers(sensor, &mut img, &flow);
    let [width, height] = sensor.image_size;
    (OpticalImage { width, height, rgb: quantize(sensor, &img, rng) }, flow)
}

/// The sensor's image model for the GPU (`robot.tactile.optical_shading: gpu`), over depth view
/// `view`; None for a calibrated light model, which the CPU shades.
pub fn gel_shading(sensor: &OpticalSensor, view: usize) -> Option<GelShading> {
    if sensor.calibration.as_ref().is_some_and(|c| c.shading().is_some()) || sensor.lights.len() > MAX_GEL_LIGHTS {
        return None;
    }
    let (px, py) = pitch(sensor);
    let sigma = sensor.elastic_spread_mm * 1e-3;
    let lights = sensor
        .lights
        .iter()
        .map(|l| {
            let d = DVec3::from_array(l.direction).normalize();
            let azimuth = glam::DVec2::new(l.direction[0], l.direction[1]).normalize_or_zero();
            GelLight { direction: d.to_array(), color: l.color, falloff: l.falloff, azimuth: azimuth.to_array() }
        })
        .collect();
    Some(GelShading {
        view,
        gel_thickness: sensor.gel_thickness_mm * 1e-3,
        pitch: [px, py],
        spread_sigma_px: if sigma > 0.0 { [sigma / px, sigma / py] } else { [0.0, 0.0] },
        lights,
        ambient: sensor.ambient,
        tint: sensor.background,
        vignetting: sensor.vignetting,
    })
}

/// The gel's slopes from the GPU's shading (its surface is each pixel's fourth value), as
/// [`gel_slopes`] gives them from the depth; None where the gel is not pushed in.
pub fn shaded_slopes(sensor: &OpticalSensor, shaded: &[f32]) -> Option<Vec<(f64, f64)>> {
    let gel: Vec<f64> = shaded.chunks_exact(4).map(|p| p[3] as f64).collect();
    gel.iter().any(|&g| g > 0.0).then(|| slopes(sensor, &gel))
}

/// The sensor's image from the GPU's shading of it (`Renderer::render_depth_views_shaded`: linear
/// R, G, B and the gel's surface per pixel): the markers (moved by the gel's slope and `shear`),
/// noise and quantization as [`optical_image`] makes them; with the marker flow painted.
pub fn optical_image_shaded(
    sensor: &OpticalSensor,
    shaded: &[f32],
    shear: Option<&GelShear>,
    rng: Option<&mut ChaCha8Rng>,
) -> (OpticalImage, Vec<MarkerMove>) {
    let img: Vec<f64> = shaded.chunks_exact(4).flat_map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect();
    let slopes = sensor.markers.and_then(|_| shaded_slopes(sensor, shaded));
    finish(sensor, img, slopes.as_deref(), shear, rng)
}

/// The sensor unit `variation` makes of the configured `sensor` (`randomization.tactile_sensors`).
pub fn varied(sensor: &OpticalSensor, variation: &vt_randomizers::SensorVariation) -> OpticalSensor {
    let mut s = sensor.clone();
    // A measured light model (its background and shading) stays the unit's: only the LED model's
    // settings vary, so a calibrated pad's `/sample/info` keeps the values it renders with.
    if s.calibration.as_ref().and_then(|c| c.shading()).is_none() {
        for (led, factors) in s.lights.iter_mut().zip(&variation.led_color) {
            led.color = std::array::from_fn(|c| led.color[c] * factors[c]);
        }
        s.background = std::array::from_fn(|c| (s.background[c] * variation.background[c]).clamp(0.0, 1.0));
        s.vignetting = (s.vignetting + variation.vignetting).clamp(0.0, 0.95);
    }
    s.gel_thickness_mm *= variation.gel_thickness;
    s.elastic_spread_mm *= variation.elastic_spread;
    if let Some(m) = s.markers.as_mut() {
        m.pitch_mm *= variation.marker_pitch;
        // The print keeps its dots apart: the radius stays below half the pitch.
        m.radius_mm = m.radius_mm.min(0.45 * m.pitch_mm);
    }
    s
}

/// Photometric stereo, the image model's inverse: the gel's inner normal per pixel of an image
/// made without markers, from the sensor's known lights, tint and vignetting (where no LED is
/// clipped, i.e. every LED lights the surface). Returns the slopes (∂g/∂x, ∂g/∂y) of the gel's
/// indentation.
pub fn slopes_from_image(sensor: &OpticalSensor, image: &OpticalImage) -> Vec<(f64, f64)> {
    let [w, h] = sensor.image_size;
    let mut out = Vec::with_capacity((w * h) as usize);
    for v in 0..h {
        for u in 0..w {
            let (at, _) = pixel_position(sensor, u, v);
            let tint = gel_color(sensor, at);
            let k = ((v * w + u) * 3) as usize;
            let b = DVec3::from_array(std::array::from_fn(|c| image.rgb[k + c] as f64 / 255.0 / tint[c] - sensor.ambient));
            let m: DMat3 = light_matrix(&sensor.lights, at);
            let n = m.inverse() * b;
            // n is the inner normal up to scale: m = -(gx, gy, 1) / |.|.
            out.push(if n.z < -1e-9 { (n.x / n.z, n.y / n.z) } else { (0.0, 0.0) });
        }
    }
    out
}

#[cfg(test)]
mod tests;
