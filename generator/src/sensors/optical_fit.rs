//! Fitting an optical sensor to a real unit from presses of a ball (Taxim's recipe): one image with
//! nothing touching the gel and several with a ball of known radius pressed in at different
//! places. The image model's inverse, as `optical::slopes_from_image` is for one image:
//! 1. **Contact:** each press's difference from the background, above the images' noise, gives
//!    the contact's outline; a circle fitted to it gives the ball's centre in the image.
//! 2. **Pixel size and light model:** inside the contact the gel takes the ball's shape, so at a
//!    candidate pixel size every pixel's distance from the centre gives the gel's normal there.
//!    The light model that is linear in the normal (the LED model's form) is fitted by least
//!    squares at each candidate; the pixel size is the one with the smallest residual (the
//!    normal's non-linearity in the slope is what tells sizes apart), and each press's centre is
//!    refined at it.
//! 3. **Two light models** are fitted at that size and the better one (smaller residual over the
//!    presses) is kept: the per-pixel-position polynomial (quadratic in the normal, cubic in the
//!    image position) and the LED model (vtgen's own: an LED per colour channel, its direction,
//!    brightness and falloff, the gel's tint and vignetting, by Levenberg–Marquardt).

use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use crate::config::optical_calibration::{CalibrationFile, NORMAL_TERMS, POSITION_TERMS, normal_terms, polynomial_delta, position_terms};
use crate::config::{Led, OpticalSensor, led_falloff};

/// One image, `w x h` RGB as 0..=1 levels.
pub struct CalibrationImage {
    pub name: String,
    pub rgb: Vec<f64>,
}

/// What a press's contact looked like.
#[derive(Debug, Clone)]
pub struct DetectedPress {
    pub name: String,
    /// The ball's centre (pixels, column and row from the image's corner).
    pub centre_px: [f64; 2],
    /// The radius (pixels) of the part of the image that differs from the background.
    pub radius_px: f64,
    /// Pixels the fit used (inside the contact).
    pub pixels: usize,
    /// RMS residual (8-bit levels) over the press's fitted pixels, for the polynomial and the LED
    /// model.
    pub rms_polynomial: f64,
    pub rms_leds: f64,
}

/// The fit's outcome.
pub struct CalibrationFit {
    pub pixel_size_mm: f64,
    /// `polynomial` or `leds`: the model with the smaller residual over the presses.
    pub chosen: &'static str,
    pub rms_polynomial: f64,
    pub rms_leds: f64,
    pub presses: Vec<DetectedPress>,
    /// The polynomial model's coefficients (per channel, normal term major).
    pub coefficients: [Vec<f64>; 3],
    /// The LED model.
    pub leds: LedFit,
    /// Seconds the fit took.
    pub seconds: f64,
}

/// The LED model's fitted parameters.
#[derive(Debug, Clone)]
pub struct LedFit {
    pub lights: Vec<Led>,
    pub ambient: f64,
    pub background: [f64; 3],
    pub vignetting: f64,
}

/// The problem as the fit sees it.
pub struct CalibrationInput<'a> {
    pub image_size: [u32; 2],
    pub background: &'a CalibrationImage,
    pub presses: &'a [CalibrationImage],
    pub ball_radius_mm: f64,
    /// A known pixel size (mm); None: fitted.
    pub pixel_size_mm: Option<f64>,
}

/// A contact pixel: its image position and the channel values minus the background.
struct Sample {
    press: usize,
    u: u32,
    v: u32,
    delta: [f64; 3],
}

/// Fits the sensor. Errors: a press whose contact cannot be found, or too few pixels to fit.
pub fn fit(input: &CalibrationInput) -> anyhow::Result<CalibrationFit> {
    let start = Instant::now();
    let [w, h] = input.image_size;
    let noise = noise_levels(input);
    let mut presses = Vec::new();
    for p in input.presses {
        let (centre, radius) = detect_contact(input, p, noise).map_err(|e| anyhow::anyhow!("{}: {e}", p.name))?;
        presses.push(DetectedPress {
            name: p.name.clone(),
            centre_px: centre,
            radius_px: radius,
            pixels: 0,
            rms_polynomial: 0.0,
            rms_leds: 0.0,
        });
    }
    let r_ball = input.ball_radius_mm * 1e-3;
    let samples = contact_samples(input, &presses);
    anyhow::ensure!(samples.len() >= 200, "only {} contact pixels over the presses: press deeper, or more presses", samples.len());
    // Pixel size: the linear (LED-form) model's residual over a log grid, then golden sections.
    let residual_at = |pitch: f64, centres: &[[f64; 2]]| linear_fit(&samples, centres, pitch, r_ball, [w, h], 3).1;
    let mut centres: Vec<[f64; 2]> = presses.iter().map(|p| p.centre_px).collect();
    let pitch = match input.pixel_size_mm {
        Some(mm) => mm * 1e-3,
        None => {
            let mut pitch = 0.0;
            for _round in 0..2 {
                let grid: Vec<f64> = (0..41).map(|k| 2e-6 * (300.0f64).powf(k as f64 / 40.0)).collect();
                let residuals: Vec<(f64, f64)> = grid.iter().map(|&p| (residual_at(p, &centres), p)).collect();
                let (_, best) = residuals.into_iter().min_by(|a, b| a.0.total_cmp(&b.0)).expect("a grid");
                pitch = golden(|p| residual_at(p, &centres), best / 1.16, best * 1.16, 30);
                centres = refine_centres(&samples, &centres, pitch, r_ball, [w, h]);
            }
            pitch
        }
    };
    if input.pixel_size_mm.is_some() {
        centres = refine_centres(&samples, &centres, pitch, r_ball, [w, h]);
    }
    let (coefficients, _) = linear_fit(&samples, &centres, pitch, r_ball, [w, h], NORMAL_TERMS.len());
    let coefficients: [Vec<f64>; 3] = std::array::from_fn(|c| coefficients[c].clone());
    let leds = fit_leds(input, &samples, &centres, pitch, r_ball, &coefficients);
    // Residuals per press and model.
    let sensor = led_sensor(input.image_size, pitch, &leds);
    let background = &input.background.rgb;
    let (mut sq_poly, mut sq_leds, mut count) = (0.0, 0.0, 0usize);
    for (k, press) in presses.iter_mut().enumerate() {
        press.centre_px = centres[k];
        let (mut sp, mut sl, mut n) = (0.0, 0.0, 0usize);
        for s in samples.iter().filter(|s| s.press == k) {
            let Some(g) = ball_slopes(s.u, s.v, centres[k], pitch, r_ball) else { continue };
            let at = position([w, h], s.u, s.v);
            let poly = polynomial_delta(&coefficients, at, g);
            let led = led_image(&sensor, at, Some(g));
            let base = (s.v * w + s.u) as usize * 3;
            for c in 0..3 {
                sp += (poly[c] - s.delta[c]).powi(2);
                sl += (led[c] - (background[base + c] + s.delta[c])).powi(2);
            }
            n += 3;
        }
        press.pixels = n / 3;
        press.rms_polynomial = 255.0 * (sp / n.max(1) as f64).sqrt();
        press.rms_leds = 255.0 * (sl / n.max(1) as f64).sqrt();
        sq_poly += sp;
        sq_leds += sl;
        count += n;
    }
    let rms_polynomial = 255.0 * (sq_poly / count.max(1) as f64).sqrt();
    let rms_leds = 255.0 * (sq_leds / count.max(1) as f64).sqrt();
    let chosen = if rms_polynomial <= rms_leds { "polynomial" } else { "leds" };
    Ok(CalibrationFit {
        pixel_size_mm: pitch * 1e3,
        chosen,
        rms_polynomial,
        rms_leds,
        presses,
        coefficients,
        leds,
        seconds: start.elapsed().as_secs_f64(),
    })
}

impl CalibrationFit {
    /// The calibration file of the chosen model (`background_image`: the PNG written beside it).
    pub fn file(&self, image_size: [u32; 2], background_image: &str) -> CalibrationFile {
        let mut f = CalibrationFile {
            model: self.chosen.into(),
            image_size,
            pixel_size_mm: self.pixel_size_mm,
            background_image: None,
            coefficients: None,
            lights: None,
            ambient: None,
            background: None,
            vignetting: None,
        };
        if self.chosen == "polynomial" {
            f.background_image = Some(background_image.into());
            f.coefficients = Some(self.coefficients.clone());
        } else {
            f.lights = Some(self.leds.lights.clone());
            f.ambient = Some(self.leds.ambient);
            f.background = Some(self.leds.background);
            f.vignetting = Some(self.leds.vignetting);
        }
        f
    }
}

/// Image position (-1..=1) of pixel (u, v)'s centre, as `optical::pixel_position`.
fn position([w, h]: [u32; 2], u: u32, v: u32) -> [f64; 2] {
    [(2.0 * u as f64 + 1.0) / w as f64 - 1.0, (2.0 * v as f64 + 1.0) / h as f64 - 1.0]
}

/// The gel's slopes at pixel (u, v) under a ball of radius `r` centred over `centre` (pixels),
/// `pitch` m per pixel: the sphere's, `-(x - cx) / sqrt(r^2 - d^2)`; None outside the ball.
fn ball_slopes(u: u32, v: u32, centre: [f64; 2], pitch: f64, r: f64) -> Option<(f64, f64)> {
    let (dx, dy) = ((u as f64 + 0.5 - centre[0]) * pitch, (v as f64 + 0.5 - centre[1]) * pitch);
    let z2 = r * r - dx * dx - dy * dy;
    (z2 > (0.2 * r).powi(2)).then(|| (-dx / z2.sqrt(), -dy / z2.sqrt()))
}

/// The pixel noise (levels, summed over the channels' absolute differences) of a press against
/// the background where nothing touches: the median over the image.
fn noise_levels(input: &CalibrationInput) -> f64 {
    let mut diffs: Vec<f64> = input
        .presses
        .iter()
        .flat_map(|p| {
            p.rgb
                .chunks_exact(3)
                .zip(input.background.rgb.chunks_exact(3))
                .map(|(a, b)| 255.0 * (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f64>())
        })
        .collect();
    let mid = diffs.len() / 2;
    diffs.select_nth_unstable_by(mid, f64::total_cmp);
    diffs[mid]
}

/// The contact of a press: the largest connected region that differs from the background by
/// more than the noise, its outer outline fitted by a circle. Returns (centre, radius) in pixels.
fn detect_contact(input: &CalibrationInput, press: &CalibrationImage, noise: f64) -> Result<([f64; 2], f64), String> {
    let [w, h] = input.image_size.map(|s| s as usize);
    let threshold = (4.0 * noise).max(6.0);
    let on: Vec<bool> = press
        .rgb
        .chunks_exact(3)
        .zip(input.background.rgb.chunks_exact(3))
        .map(|(a, b)| 255.0 * (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f64>() > threshold)
        .collect();
    // Largest 8-connected component.
    let mut label = vec![0u32; w * h];
    let (mut best, mut best_size, mut next) = (0u32, 0usize, 0u32);
    for start in 0..w * h {
        if !on[start] || label[start] != 0 {
            continue;
        }
        next += 1;
        let (mut stack, mut size) = (vec![start], 0usize);
        label[start] = next;
        while let Some(k) = stack.pop() {
            size += 1;
            let (x, y) = ((k % w) as i64, (k / w) as i64);
            for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                    let n = ny as usize * w + nx as usize;
                    if on[n] && label[n] == 0 {
                        label[n] = next;
                        stack.push(n);
                    }
                }
            }
        }
        if size > best_size {
            (best, best_size) = (next, size);
        }
    }
    if best_size < 30 {
        return Err(format!("no contact found (at most {best_size} pixels differ from the background by more than {threshold:.0} levels)"));
    }
    // The outer outline: component pixels with a 4-neighbour outside it, farthest from the centroid
    // in their direction (the ring's inner edge, around the flat centre of the press, is not).
    let pixels: Vec<usize> = (0..w * h).filter(|&k| label[k] == best).collect();
    let centroid = pixels.iter().fold([0.0, 0.0], |a, &k| [a[0] + (k % w) as f64 + 0.5, a[1] + (k / w) as f64 + 0.5]);
    let centroid = centroid.map(|c| c / pixels.len() as f64);
    let mut outline: Vec<[f64; 2]> = Vec::new();
    let mut by_angle = vec![(0.0f64, [0.0f64; 2]); 180];
    for &k in &pixels {
        let p = [(k % w) as f64 + 0.5, (k / w) as f64 + 0.5];
        let (dx, dy) = (p[0] - centroid[0], p[1] - centroid[1]);
        let bin = (((dy.atan2(dx) + std::f64::consts::PI) / std::f64::consts::TAU * 180.0) as usize).min(179);
        let d = dx.hypot(dy);
        if d > by_angle[bin].0 {
            by_angle[bin] = (d, p);
        }
    }
    outline.extend(by_angle.iter().filter(|(d, _)| *d > 0.0).map(|(_, p)| *p));
    // Kåsa's circle fit: x^2 + y^2 + D x + E y + F = 0.
    let mut a = DMatrix::<f64>::zeros(outline.len(), 3);
    let mut b = DVector::<f64>::zeros(outline.len());
    for (i, p) in outline.iter().enumerate() {
        a[(i, 0)] = p[0];
        a[(i, 1)] = p[1];
        a[(i, 2)] = 1.0;
        b[i] = -(p[0] * p[0] + p[1] * p[1]);
    }
    let x = (a.transpose() * &a).lu().solve(&(a.transpose() * b)).ok_or("the contact's outline is degenerate")?;
    let centre = [-x[0] / 2.0, -x[1] / 2.0];
    let radius = (centre[0] * centre[0] + centre[1] * centre[1] - x[2]).max(0.0).sqrt();
    Ok((centre, radius))
}

/// The pixels inside each press's contact (within 0.6 of the outline's radius: where the gel has
/// the ball's shape, away from its elastic spread around the rim).
fn contact_samples(input: &CalibrationInput, presses: &[DetectedPress]) -> Vec<Sample> {
    let [w, h] = input.image_size;
    let mut out = Vec::new();
    for (k, p) in presses.iter().enumerate() {
        let img = &input.presses[k].rgb;
        for v in 0..h {
            for u in 0..w {
                let d = (u as f64 + 0.5 - p.centre_px[0]).hypot(v as f64 + 0.5 - p.centre_px[1]);
                if d < 0.6 * p.radius_px {
                    let base = (v * w + u) as usize * 3;
                    out.push(Sample { press: k, u, v, delta: std::array::from_fn(|c| img[base + c] - input.background.rgb[base + c]) });
                }
            }
        }
    }
    out
}

/// Least squares of the polynomial model with the first `normal_terms` normal terms (3: the
/// LED model's linear form; 6: the full polynomial) at a pixel size and centres. Returns the
/// coefficients per channel (zero-padded to the full model) and the mean squared residual.
fn linear_fit(
    samples: &[Sample],
    centres: &[[f64; 2]],
    pitch: f64,
    r: f64,
    size: [u32; 2],
    normal_terms_used: usize,
) -> ([Vec<f64>; 3], f64) {
    let np = POSITION_TERMS.len();
    let k = normal_terms_used * np;
    let mut ata = DMatrix::<f64>::zeros(k, k);
    let mut atb: [DVector<f64>; 3] = std::array::from_fn(|_| DVector::zeros(k));
    let mut rows = Vec::with_capacity(samples.len());
    let mut row = vec![0.0; k];
    // A contact pixel the ball at this pixel size does not reach is one the model cannot explain:
    // its whole difference from the background counts (else a large size would fit few pixels).
    let mut outside = 0.0;
    for s in samples {
        let Some(g) = ball_slopes(s.u, s.v, centres[s.press], pitch, r) else {
            outside += s.delta.iter().map(|d| d * d).sum::<f64>();
            continue;
        };
        let (n, p) = (normal_terms(g), position_terms(position(size, s.u, s.v)));
        for j in 0..normal_terms_used {
            for (i, pi) in p.iter().enumerate() {
                row[j * np + i] = n[j] * pi;
            }
        }
        // Rank-one update of the normal equations (upper triangle, mirrored below).
        for a in 0..k {
            let ra = row[a];
            if ra == 0.0 {
                continue;
            }
            for b in a..k {
                ata[(a, b)] += ra * row[b];
            }
            for (c, atb) in atb.iter_mut().enumerate() {
                atb[a] += ra * s.delta[c];
            }
        }
        rows.push((row.clone(), s.delta));
    }
    if rows.len() < k {
        return (std::array::from_fn(|_| vec![0.0; NORMAL_TERMS.len() * np]), f64::INFINITY);
    }
    for a in 0..k {
        for b in 0..a {
            ata[(a, b)] = ata[(b, a)];
        }
    }
    let ridge = 1e-10 * (0..k).map(|a| ata[(a, a)]).sum::<f64>() / k as f64;
    for a in 0..k {
        ata[(a, a)] += ridge;
    }
    let Some(chol) = ata.cholesky() else { return (std::array::from_fn(|_| vec![0.0; NORMAL_TERMS.len() * np]), f64::INFINITY) };
    let x: [DVector<f64>; 3] = std::array::from_fn(|c| chol.solve(&atb[c]));
    let mut sq = outside;
    for (row, delta) in &rows {
        for c in 0..3 {
            let model: f64 = row.iter().zip(x[c].iter()).map(|(a, b)| a * b).sum();
            sq += (model - delta[c]).powi(2);
        }
    }
    let coefficients = std::array::from_fn(|c| {
        let mut full = vec![0.0; NORMAL_TERMS.len() * np];
        full[..k].copy_from_slice(x[c].as_slice());
        full
    });
    (coefficients, sq / (3 * samples.len()) as f64)
}

/// Each press's centre moved (within ±1.5 px) to where the linear model fits its pixels best.
fn refine_centres(samples: &[Sample], centres: &[[f64; 2]], pitch: f64, r: f64, size: [u32; 2]) -> Vec<[f64; 2]> {
    let mut centres = centres.to_vec();
    for _round in 0..2 {
        for k in 0..centres.len() {
            let mut best = (linear_fit(samples, &centres, pitch, r, size, 3).1, centres[k]);
            let origin = centres[k];
            for step in [0.5, 0.2, 0.05] {
                let around = best.1;
                for (dx, dy) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (-1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (1.0, -1.0)] {
                    let c = [around[0] + dx * step, around[1] + dy * step];
                    if (c[0] - origin[0]).abs() > 1.5 || (c[1] - origin[1]).abs() > 1.5 {
                        continue;
                    }
                    centres[k] = c;
                    let e = linear_fit(samples, &centres, pitch, r, size, 3).1;
                    if e < best.0 {
                        best = (e, c);
                    }
                }
            }
            centres[k] = best.1;
        }
    }
    centres
}

/// The minimum of a unimodal `f` on `[a, b]` by golden sections.
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, iterations: usize) -> f64 {
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - phi * (b - a), a + phi * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iterations {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - phi * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + phi * (b - a);
            fd = f(d);
        }
    }
    (a + b) / 2.0
}

/// The sensor of an LED fit (image size and pixel size given), for its shading.
fn led_sensor(image_size: [u32; 2], pitch: f64, leds: &LedFit) -> OpticalSensor {
    let mut s = crate::config::OpticalPreset::GelsightMini.sensor();
    s.image_size = image_size;
    s.sensing_area_mm = image_size.map(|n| n as f64 * pitch * 1e3);
    s.lights = leds.lights.clone();
    s.ambient = leds.ambient;
    s.background = leds.background;
    s.vignetting = leds.vignetting;
    s
}

/// The LED model's linear intensity (0..=1) at image position `at` for the gel's slopes (None:
/// flat), as `optical::shade` makes it.
fn led_image(sensor: &OpticalSensor, at: [f64; 2], g: Option<(f64, f64)>) -> [f64; 3] {
    let (gx, gy) = g.unwrap_or((0.0, 0.0));
    let m = glam::DVec3::new(-gx, -gy, -1.0).normalize();
    let mut light = [sensor.ambient; 3];
    for l in &sensor.lights {
        let lit = led_falloff(l, at) * m.dot(glam::DVec3::from_array(l.direction).normalize()).max(0.0);
        for (c, k) in light.iter_mut().zip(l.color) {
            *c += lit * k;
        }
    }
    let vig = 1.0 - sensor.vignetting * 0.5 * (at[0] * at[0] + at[1] * at[1]);
    std::array::from_fn(|c| sensor.background[c] * vig * light[c])
}

/// A pixel the LED fit matches: (u, v), the gel's slopes there (None: flat), its image values.
type LedPoint = (u32, u32, Option<(f64, f64)>, [f64; 3]);

/// The LED model: one LED per colour channel (the polynomial's linear part at the image centre
/// gives each its direction and brightness), the gel's tint from the background's centre and
/// the preset's ambient light, then Levenberg–Marquardt on every parameter over the contact
/// pixels and a grid of background pixels.
fn fit_leds(
    input: &CalibrationInput,
    samples: &[Sample],
    centres: &[[f64; 2]],
    pitch: f64,
    r: f64,
    coefficients: &[Vec<f64>; 3],
) -> LedFit {
    let [w, h] = input.image_size;
    let np = POSITION_TERMS.len();
    let ambient = 0.15;
    let centre_bg: [f64; 3] = {
        let (u, v) = (w / 2, h / 2);
        let base = (v * w + u) as usize * 3;
        std::array::from_fn(|c| input.background.rgb[base + c])
    };
    // Channel c's light vector at the centre: its coefficients of mx, my and 1 + mz.
    let rows: [glam::DVec3; 3] =
        std::array::from_fn(|c| glam::DVec3::new(coefficients[c][0], coefficients[c][np], coefficients[c][2 * np]));
    let tint: [f64; 3] = std::array::from_fn(|c| ((centre_bg[c] + rows[c].z) / ambient).clamp(0.05, 1.0));
    let mut params: Vec<f64> = Vec::new();
    for (c, row) in rows.iter().enumerate() {
        let d = if row.z < -1e-6 { row.normalize() } else { glam::DVec3::new(0.0, 0.0, -1.0) };
        let elevation = (-d.z).asin();
        let azimuth = d.y.atan2(d.x);
        params.extend([azimuth, elevation, row.length() / tint[c], 0.0]);
    }
    params.extend(tint);
    params.push(0.0);
    let to_fit = |p: &[f64]| -> LedFit {
        let lights = (0..3)
            .map(|c| {
                let (az, el, bright, falloff) = (p[4 * c], p[4 * c + 1], p[4 * c + 2], p[4 * c + 3]);
                let mut color = [0.0; 3];
                color[c] = bright.clamp(0.0, 4.0);
                Led {
                    direction: [el.cos() * az.cos(), el.cos() * az.sin(), -el.sin().abs().max(1e-3)],
                    color,
                    falloff: falloff.clamp(0.0, 1.0),
                }
            })
            .collect();
        LedFit { lights, ambient, background: std::array::from_fn(|c| p[12 + c].clamp(0.0, 1.0)), vignetting: p[15].clamp(0.0, 0.95) }
    };
    // The residuals: contact pixels (a subsample of at most 4000) and a 16 x 12 grid of background pixels.
    let stride = (samples.len() / 4000).max(1);
    let points: Vec<LedPoint> = samples
        .iter()
        .step_by(stride)
        .filter_map(|s| {
            let g = ball_slopes(s.u, s.v, centres[s.press], pitch, r)?;
            let base = (s.v * w + s.u) as usize * 3;
            Some((s.u, s.v, Some(g), std::array::from_fn(|c| input.background.rgb[base + c] + s.delta[c])))
        })
        .chain((0..12).flat_map(|j| (0..16).map(move |i| (i, j))).map(|(i, j)| {
            let (u, v) = ((2 * i + 1) * w / 32, (2 * j + 1) * h / 24);
            let base = (v * w + u) as usize * 3;
            (u, v, None, std::array::from_fn(|c| input.background.rgb[base + c]))
        }))
        .collect();
    let residuals = |p: &[f64]| -> Vec<f64> {
        let sensor = led_sensor(input.image_size, pitch, &to_fit(p));
        points
            .iter()
            .flat_map(|(u, v, g, target)| {
                let m = led_image(&sensor, position([w, h], *u, *v), *g);
                (0..3).map(move |c| m[c] - target[c])
            })
            .collect()
    };
    let mut lambda = 1e-3;
    let mut res = residuals(&params);
    let mut cost: f64 = res.iter().map(|r| r * r).sum();
    for _ in 0..40 {
        let n = params.len();
        let mut jac = DMatrix::<f64>::zeros(res.len(), n);
        for k in 0..n {
            let mut q = params.clone();
            let step = 1e-6 * params[k].abs().max(1e-3);
            q[k] += step;
            for (i, r2) in residuals(&q).iter().enumerate() {
                jac[(i, k)] = (r2 - res[i]) / step;
            }
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * DVector::from_vec(res.clone());
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for k in 0..n {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(delta) = a.lu().solve(&(-&jtr)) else { break };
            let q: Vec<f64> = params.iter().zip(delta.iter()).map(|(p, d)| p + d).collect();
            let r2 = residuals(&q);
            let c2: f64 = r2.iter().map(|r| r * r).sum();
            if c2 < cost {
                (params, res, cost) = (q, r2, c2);
                lambda = (lambda / 3.0).max(1e-9);
                improved = true;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    to_fit(&params)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball's slopes point away from its centre and steepen towards its rim.
    #[test]
    fn a_ball_slopes_down_from_its_centre() {
        let (gx, gy) = ball_slopes(10, 5, [5.5, 5.5], 1e-4, 2e-3).unwrap();
        assert!(gx < 0.0 && gy.abs() < 1e-12, "{gx} {gy}");
        let (steeper, _) = ball_slopes(20, 5, [5.5, 5.5], 1e-4, 2e-3).unwrap();
        assert!(steeper < gx);
        assert!(ball_slopes(40, 5, [5.5, 5.5], 1e-4, 2e-3).is_none(), "outside the ball");
    }

    #[test]
    fn golden_sections_find_a_minimum() {
        let x = golden(|x| (x - 0.37).powi(2), 0.0, 1.0, 60);
        assert!((x - 0.37).abs() < 1e-6, "{x}");
    }
}
