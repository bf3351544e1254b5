//! Fitting an optical sensor to a real unit from presses of a ball (Taxim's recipe): one image with
//! nothing touching the gel and several with a ball of known radius pressed in at different
//! places. The image model's inverse, as `optical::slopes_from_image` is for one image:
//! 1. **Contact:** each press's difference from the background, less the lighting's drift between
//!    the two (a smooth surface per channel, fitted robustly over the whole image) and without the
//!    printed markers, above the images' noise, gives the contact's outline; a circle fitted
//!    robustly to it gives the ball's centre in the image and the visible radius. A press whose
//!    outline is not round is rejected and listed.
//! 2. **Pixel size:** given (`--pixel-size-mm`, measured on the unit), or identified from the
//!    shape of the presses (the light model linear in the gel's normal fitted at each candidate:
//!    its non-linearity in the slope is what tells sizes apart) when that shape fixes it; when the
//!    residual is flat over sizes the fit refuses and asks for the size rather than guessing.
//! 3. **Gel shape:** a press of depth `d` shows the ball's cap out to the contact radius
//!    `a = sqrt(2 R d - d^2)` and the gel's elastic spread around it, so the visible radius is a
//!    little larger than `a`: `a` is a share `κ` of it. The gel's surface over every press is
//!    vtgen's own gel model (`optical::gel_surface`: the ball's cap, then the spread of width `σ`),
//!    so the light model is fitted on the slopes the renderer will give it; `κ` and `σ` are those
//!    with the smallest residual over the presses.
//! 4. **Light model**, over the whole visible disc, rim included (slopes to the steepest the
//!    presses show): the per-pixel-position polynomial (quadratic in the normal, cubic in the
//!    image position), least squares by normal equations accumulated press by press (the fit's
//!    time is linear in the number of presses); each press's centre refined against it; presses
//!    that do not fit the others (a misdetected contact) rejected and listed, then refitted. The
//!    LED model (vtgen's own, by Levenberg–Marquardt) is fitted too and kept when it fits better.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use crate::config::optical_calibration::{
    CalibrationFile, LightModel, LoadedCalibration, NORMAL_TERMS, POSITION_TERMS, normal_terms, polynomial_delta, position_terms,
};
use crate::config::{Led, OpticalSensor, SensorCalibration, led_falloff};
use crate::sensors::optical::{ball_press_depth, gel_surface, indentation, slopes};

/// One image, `w x h` RGB as 0..=1 levels.
pub struct CalibrationImage {
    pub name: String,
    pub rgb: Vec<f64>,
}

/// Where a press touched, as its image shows it.
#[derive(Debug, Clone)]
pub struct Contact {
    /// The ball's centre (pixels, column and row from the image's corner).
    pub centre_px: [f64; 2],
    /// The radius (pixels) of the part of the image that differs from the background.
    pub radius_px: f64,
    /// The lighting's drift from the background to this image: per channel, the coefficients
    /// of `[1, x, y, x^2, x y, y^2]` (x, y in -1..=1 over the image), 0..=1 per level.
    pub drift: [[f64; 6]; 3],
    /// The threshold (8-bit levels, summed over the channels) above which a pixel differs.
    pub threshold: f64,
}

/// What the fit made of one press.
#[derive(Debug, Clone)]
pub struct DetectedPress {
    pub name: String,
    /// The contact as detected, then refined (its centre) against the light model.
    pub contact: Option<Contact>,
    /// Why the press was left out of the fit (None: used).
    pub rejected: Option<String>,
    /// How deep the ball pressed (mm), from the contact radius.
    pub depth_mm: f64,
    /// Pixels the fit used (the visible disc without markers).
    pub pixels: usize,
    /// RMS residual (8-bit levels) over the press's fitted pixels, for the polynomial and the LED
    /// model.
    pub rms_polynomial: f64,
    pub rms_leds: f64,
}

/// The fit's outcome.
pub struct CalibrationFit {
    pub pixel_size_mm: f64,
    /// How the pixel size came: `given` or `identified`.
    pub pixel_size_source: &'static str,
    /// The gel's elastic spread (mm) and the contact radius over the visible one, fitted.
    pub elastic_spread_mm: f64,
    pub contact_ratio: f64,
    /// How many of the image-position terms the polynomial uses (1, 3, 6 or 10: constant to
    /// cubic), chosen by leaving each press out in turn, and the RMS (levels) of that check.
    pub position_terms: usize,
    pub rms_cross_validated: f64,
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
    /// A known pixel size (mm); None: identified from the presses, or refused.
    pub pixel_size_mm: Option<f64>,
}

/// A contact pixel: its press, position, the channels' change from the background (drift
/// removed) and the gel's slopes there (at the current geometry).
#[derive(Clone)]
struct Sample {
    u: u32,
    v: u32,
    delta: [f64; 3],
    slope: (f64, f64),
}

/// The unit's background, prepared once: where its printed markers are.
pub struct Prepared<'a> {
    input: &'a CalibrationInput<'a>,
    /// Pixels the fit leaves out: markers printed on the gel (dark spots of the background).
    marker: Vec<bool>,
}

/// The contact ratios and elastic spreads (mm) the fit tries.
const CONTACT_RATIOS: [f64; 7] = [0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0];
const SPREADS_MM: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

impl<'a> Prepared<'a> {
    pub fn new(input: &'a CalibrationInput<'a>) -> Self {
        let [w, h] = input.image_size.map(|s| s as usize);
        let grey: Vec<f64> = input.background.rgb.chunks_exact(3).map(|p| 255.0 * (p[0] + p[1] + p[2]) / 3.0).collect();
        let local = box_blur(&grey, w, h, 6);
        let dark: Vec<bool> = grey.iter().zip(&local).map(|(g, l)| l - g > 12.0).collect();
        Prepared { input, marker: dilate(&dark, w, h, 2) }
    }

    /// The pixels of `press` the fit leaves out: the background's markers, and the press's own
    /// (darker than the background in every channel, as Taxim masks them), slightly grown.
    fn mask(&self, press: &CalibrationImage) -> Vec<bool> {
        let [w, h] = self.input.image_size.map(|s| s as usize);
        let dark: Vec<bool> = press
            .rgb
            .chunks_exact(3)
            .zip(self.input.background.rgb.chunks_exact(3))
            .map(|(p, b)| (0..3).all(|c| 255.0 * (b[c] - p[c]) > 30.0))
            .collect();
        let dark = dilate(&dark, w, h, 2);
        dark.iter().zip(&self.marker).map(|(a, b)| *a || *b).collect()
    }

    /// The contact of a press: its difference from the background less the lighting's drift,
    /// the largest connected region above the noise, its outline fitted by a circle (robustly).
    pub fn detect(&self, press: &CalibrationImage) -> Result<Contact, String> {
        let input = self.input;
        let [w, h] = input.image_size.map(|s| s as usize);
        let mask = self.mask(press);
        let drift = fit_drift(input, press, &mask);
        let mut magnitude = vec![0.0; w * h];
        for (k, m) in magnitude.iter_mut().enumerate() {
            if mask[k] {
                continue;
            }
            let at = position(input.image_size, (k % w) as u32, (k / w) as u32);
            let d = drift_at(&drift, at);
            *m = 255.0 * (0..3).map(|c| (press.rgb[3 * k + c] - input.background.rgb[3 * k + c] - d[c]).abs()).sum::<f64>();
        }
        // Markers' holes take their neighbours' mean (a normalized box filter over the unmasked
        // pixels), so a marker on the rim does not notch the outline; then a 1-pixel box blur
        // against the noise.
        let weight: Vec<f64> = mask.iter().map(|&m| if m { 0.0 } else { 1.0 }).collect();
        let (sum, count) = (box_blur(&magnitude, w, h, 5), box_blur(&weight, w, h, 5));
        let magnitude: Vec<f64> = (0..w * h).map(|k| if mask[k] && count[k] > 0.0 { sum[k] / count[k] } else { magnitude[k] }).collect();
        let magnitude = box_blur(&magnitude, w, h, 1);
        let mut sorted: Vec<f64> = magnitude.iter().zip(&mask).filter(|(_, m)| !**m).map(|(v, _)| *v).collect();
        if sorted.is_empty() {
            return Err("every pixel is masked as a marker".into());
        }
        let mid = sorted.len() / 2;
        sorted.select_nth_unstable_by(mid, f64::total_cmp);
        let threshold = (5.0 * sorted[mid]).max(6.0);
        let on: Vec<bool> = magnitude.iter().map(|&m| m > threshold).collect();
        // An opening (erode, then grow back) drops the thin rims moved markers leave, which would
        // otherwise join the contact and ragged its outline; the contact's disc survives it.
        let on = open_mask(&on, w, h, 2);
        let (pixels, size) = largest_component(&on, w, h);
        if size < 30 {
            return Err(format!("no contact found (at most {size} pixels differ from the background by more than {threshold:.0} levels)"));
        }
        // The outer outline: per direction from the centroid, the component's farthest pixel.
        let centroid = pixels.iter().fold([0.0, 0.0], |a, &k| [a[0] + (k % w) as f64 + 0.5, a[1] + (k / w) as f64 + 0.5]);
        let centroid = centroid.map(|c| c / pixels.len() as f64);
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
        let outline: Vec<[f64; 2]> = by_angle.iter().filter(|(d, _)| *d > 0.0).map(|(_, p)| *p).collect();
        let (centre, radius, roundness) = robust_circle(&outline).ok_or("the contact's outline is degenerate")?;
        if roundness > 0.15 {
            return Err(format!(
                "its contact is not round (half its outline is more than {:.0} % of its radius off a circle: a crescent, or two contacts)",
                100.0 * roundness
            ));
        }
        Ok(Contact { centre_px: centre, radius_px: radius, drift, threshold })
    }

    /// The visible disc's pixels of a press (markers left out), their change from the background
    /// less the drift; slopes not yet set.
    fn disc_samples(&self, press: &CalibrationImage, contact: &Contact) -> Vec<Sample> {
        let input = self.input;
        let [w, h] = input.image_size;
        let mask = self.mask(press);
        let (c, r) = (contact.centre_px, contact.radius_px);
        let (u0, u1) = ((c[0] - r).floor().max(0.0) as u32, ((c[0] + r).ceil() as u32).min(w));
        let (v0, v1) = ((c[1] - r).floor().max(0.0) as u32, ((c[1] + r).ceil() as u32).min(h));
        let mut out = Vec::new();
        for v in v0..v1 {
            for u in u0..u1 {
                let k = (v * w + u) as usize;
                if mask[k] || (u as f64 + 0.5 - c[0]).hypot(v as f64 + 0.5 - c[1]) > r {
                    continue;
                }
                let d = drift_at(&contact.drift, position(input.image_size, u, v));
                let delta = std::array::from_fn(|ch| press.rgb[3 * k + ch] - input.background.rgb[3 * k + ch] - d[ch]);
                out.push(Sample { u, v, delta, slope: (0.0, 0.0) });
            }
        }
        out
    }
}

/// The printed marker grid's period (pixels) along the image's columns and rows: the first strong
/// peak of the autocorrelation of the markers' column and row profiles in the background (their
/// dark spots), refined at the farthest multiple that still peaks. Errors: no regular grid.
pub fn marker_period_px(background: &CalibrationImage, [w, h]: [u32; 2]) -> Result<[f64; 2], String> {
    let (w, h) = (w as usize, h as usize);
    let grey: Vec<f64> = background.rgb.chunks_exact(3).map(|p| 255.0 * (p[0] + p[1] + p[2]) / 3.0).collect();
    let local = box_blur(&grey, w, h, 6);
    let dark: Vec<f64> = grey.iter().zip(&local).map(|(g, l)| if l - g > 12.0 { 1.0 } else { 0.0 }).collect();
    let spots = dark.iter().sum::<f64>();
    if spots < 20.0 {
        return Err("the background shows no printed markers (dark spots)".into());
    }
    let period = |profile: Vec<f64>, axis: &str| -> Result<f64, String> {
        let n = profile.len();
        let mean = profile.iter().sum::<f64>() / n as f64;
        let x: Vec<f64> = profile.iter().map(|v| v - mean).collect();
        let auto = |lag: usize| x.iter().zip(&x[lag..]).map(|(a, b)| a * b).sum::<f64>() / (n - lag) as f64;
        let max_lag = n / 3;
        let r: Vec<f64> = (0..=max_lag).map(auto).collect();
        // The first local maximum after the autocorrelation first turns negative.
        let start = r.iter().position(|&v| v < 0.0).ok_or_else(|| format!("no periodic markers along the {axis}"))?;
        let peak = (start + 1..max_lag).find(|&k| r[k] > r[k - 1] && r[k] >= r[k + 1] && r[k] > 0.3 * r[0]);
        let peak = peak.ok_or_else(|| format!("the markers along the {axis} are not a regular grid"))?;
        let refine = |k: usize| {
            let (a, b, c) = (r[k - 1], r[k], r[k + 1]);
            let d = a - 2.0 * b + c;
            k as f64 + if d.abs() > 1e-12 { 0.5 * (a - c) / d } else { 0.0 }
        };
        let first = refine(peak);
        // The farthest multiple that still peaks pins the period best.
        let mut best = first;
        for m in 2.. {
            let centre = (m as f64 * first).round() as usize;
            if centre + 2 > max_lag {
                break;
            }
            let k = (centre - 2..=centre + 2).max_by(|a, b| r[*a].total_cmp(&r[*b])).expect("a window");
            if r[k] < 0.3 * r[0] || k == centre - 2 || k == centre + 2 {
                break;
            }
            best = refine(k) / m as f64;
        }
        Ok(best)
    };
    let columns: Vec<f64> = (0..w).map(|u| (0..h).map(|v| dark[v * w + u]).sum()).collect();
    let rows: Vec<f64> = (0..h).map(|v| dark[v * w..(v + 1) * w].iter().sum()).collect();
    Ok([period(columns, "image's width")?, period(rows, "image's height")?])
}

/// The geometry of the fit: pixel size (m), ball radius (m), contact ratio, spread (m).
#[derive(Debug, Clone, Copy)]
struct Geometry {
    pitch: f64,
    ball: f64,
    contact_ratio: f64,
    spread: f64,
}

impl Geometry {
    /// The press's depth (m) for a visible radius (pixels).
    fn depth(&self, radius_px: f64) -> f64 {
        let a = (self.contact_ratio * radius_px * self.pitch).min(self.ball);
        self.ball - (self.ball * self.ball - a * a).sqrt()
    }
}

/// The gel's slopes at `pixels` under a ball pressed at `centre` (pixels) with visible radius
/// `radius_px`: vtgen's own gel model (the cap, then the elastic spread) over a window around it.
fn press_slopes(geometry: Geometry, centre: [f64; 2], radius_px: f64, pixels: &mut [Sample]) {
    if pixels.is_empty() {
        return;
    }
    let margin = (3.0 * geometry.spread / geometry.pitch).ceil() + 3.0;
    let (u0, v0) = ((centre[0] - radius_px - margin).floor(), (centre[1] - radius_px - margin).floor());
    let size = (2.0 * (radius_px + margin)).ceil() as u32 + 2;
    let mut window = crate::config::OpticalPreset::GelsightMini.sensor();
    window.image_size = [size, size];
    window.sensing_area_mm = [size as f64 * geometry.pitch * 1e3; 2];
    window.elastic_spread_mm = geometry.spread * 1e3;
    window.gel_thickness_mm = 4.0 * geometry.ball * 1e3;
    let half = size as f64 / 2.0;
    let at = [(centre[0] - u0 - half) * geometry.pitch, (centre[1] - v0 - half) * geometry.pitch];
    let depth = ball_press_depth(&window, geometry.ball, geometry.depth(radius_px), at);
    let gel = gel_surface(&window, &indentation(&window, &depth));
    let slope = slopes(&window, &gel);
    for s in pixels.iter_mut() {
        let (x, y) = (s.u as f64 - u0, s.v as f64 - v0);
        s.slope = if x >= 0.0 && y >= 0.0 && (x as u32) < size && (y as u32) < size {
            slope[(y as u32 * size + x as u32) as usize]
        } else {
            (0.0, 0.0)
        };
    }
}

/// Fits the sensor. Errors: fewer than two usable presses, too few pixels to fit, a pixel size the
/// presses do not fix (and none given), a ball radius the images contradict.
pub fn fit(input: &CalibrationInput) -> anyhow::Result<CalibrationFit> {
    let start = Instant::now();
    let prepared = Prepared::new(input);
    let mut presses: Vec<DetectedPress> = input
        .presses
        .iter()
        .map(|p| {
            let (contact, rejected) = match prepared.detect(p) {
                Ok(c) => (Some(c), None),
                Err(e) => (None, Some(e)),
            };
            DetectedPress { name: p.name.clone(), contact, rejected, depth_mm: 0.0, pixels: 0, rms_polynomial: 0.0, rms_leds: 0.0 }
        })
        .collect();
    let usable = |presses: &[DetectedPress]| presses.iter().filter(|p| p.rejected.is_none()).count();
    if usable(&presses) < 2 {
        let why: Vec<String> = presses.iter().filter_map(|p| p.rejected.as_ref().map(|r| format!("{}: {r}", p.name))).collect();
        anyhow::bail!("fewer than 2 presses show a usable contact:\n  {}", why.join("\n  "));
    }
    let ball = input.ball_radius_mm * 1e-3;
    let mut samples: Vec<Vec<Sample>> = presses
        .iter()
        .zip(input.presses)
        .map(|(p, img)| p.contact.as_ref().filter(|_| p.rejected.is_none()).map_or_else(Vec::new, |c| prepared.disc_samples(img, c)))
        .collect();
    let widest =
        presses.iter().filter(|p| p.rejected.is_none()).filter_map(|p| p.contact.as_ref()).map(|c| c.radius_px).fold(0.0, f64::max);

    // The pixel size: given, or identified from the presses' shape.
    let profile = |ball_px: f64| -> f64 {
        let geometry = Geometry { pitch: ball / ball_px, ball, contact_ratio: 1.0, spread: 0.0 };
        let mut normal = Normal::new(3);
        for (p, s) in presses.iter().zip(&samples) {
            let Some(c) = p.contact.as_ref().filter(|_| p.rejected.is_none()) else { continue };
            // Inside 0.6 of the visible radius the gel has the ball's shape (for a spread narrower
            // than the contact).
            let inner: Vec<Sample> = s
                .iter()
                .filter(|q| (q.u as f64 + 0.5 - c.centre_px[0]).hypot(q.v as f64 + 0.5 - c.centre_px[1]) < 0.6 * c.radius_px)
                .map(|q| Sample { slope: sphere_slope(q, c.centre_px, geometry), ..q.clone() })
                .collect();
            normal.add(&inner, input.image_size);
        }
        normal.solve().map_or(f64::INFINITY, |(_, sq)| sq)
    };
    let identify = || -> Result<f64, String> {
        // Ball radii in pixels from 0.7 of the widest visible contact (its spread makes it wider
        // than the ball's contact) to 40 times it.
        let first = 0.7 * widest;
        let grid: Vec<f64> = (0..41).map(|k| first * (40.0 * widest / first).powf(k as f64 / 40.0)).collect();
        let values: Vec<f64> = grid.iter().map(|&b| profile(b)).collect();
        let best = (0..grid.len()).min_by(|a, b| values[*a].total_cmp(&values[*b])).expect("a grid");
        let lo = if best > 0 { grid[best - 1] } else { grid[0] };
        let hi = if best + 1 < grid.len() { grid[best + 1] } else { grid[best] };
        let ball_px = golden(profile, lo, hi, 30);
        let min = profile(ball_px);
        // The sizes whose residual is within 2 % of the best: the presses cannot tell them apart.
        let flat: Vec<f64> = grid.iter().zip(&values).filter(|(_, v)| **v <= 1.02 * min).map(|(b, _)| *b).collect();
        let (flat_lo, flat_hi) = (flat.iter().cloned().fold(ball_px, f64::min), flat.iter().cloned().fold(ball_px, f64::max));
        let at_edge = best == 0 || best + 1 == grid.len();
        if at_edge || flat_lo < 0.95 * ball_px || flat_hi > 1.05 * ball_px {
            return Err(format!(
                "the presses do not fix the pixel size: the light model fits them within 2 % as well at any size from {:.4} to {:.4} mm \
                 per pixel{}. Give it with --pixel-size-mm: press something of known length (a caliper's jaws, a ruler's edge) on the \
                 gel and divide its length in mm by its length in pixels",
                ball / flat_hi * 1e3,
                ball / flat_lo * 1e3,
                if at_edge { " (the best is at the edge of the search)" } else { "" }
            ));
        }
        Ok(ball / ball_px)
    };
    let (pitch, pixel_size_source) = match input.pixel_size_mm {
        Some(mm) => (mm * 1e-3, "given"),
        None => (identify().map_err(|e| anyhow::anyhow!(e))?, "identified"),
    };
    // A ball narrower than its contacts (even if half the visible disc is the gel's spread): the
    // radius is wrong, or the pixel size.
    if CONTACT_RATIOS[0] * widest * pitch > ball {
        anyhow::bail!(
            "the widest contact is {:.2} mm in radius ({widest:.1} pixels of {:.4} mm), more than 2.5 times the ball's {} mm radius: \
             --ball-radius is the radius (half the diameter), and --pixel-size-mm the size of one pixel on the gel",
            widest * pitch * 1e3,
            pitch * 1e3,
            input.ball_radius_mm
        );
    }
    // A given size the presses' shape contradicts, when their shape fixes it.
    if input.pixel_size_mm.is_some()
        && let Ok(identified) = identify()
        && !(0.7..=1.4).contains(&(pitch / identified))
    {
        anyhow::bail!(
            "the presses' shape says the ball is {:.1} pixels in radius; --ball-radius {} mm at --pixel-size-mm {} makes it {:.1}: \
             is the ball's diameter given as its radius, or the pixel size off?",
            ball / identified,
            input.ball_radius_mm,
            pitch * 1e3,
            ball / pitch
        );
    }

    // The gel's geometry: the contact ratio and spread with the smallest residual.
    // The model at a geometry: per press normal equations, the image-position degree chosen by
    // leaving each press out in turn (few presses cannot pin a cubic over the image).
    let solve_at = |geometry: Geometry, presses: &[DetectedPress], samples: &mut [Vec<Sample>]| -> Option<Solved> {
        let normals: Vec<Normal> = presses
            .iter()
            .zip(samples.iter_mut())
            .filter_map(|(p, s)| {
                let c = p.contact.as_ref().filter(|_| p.rejected.is_none())?;
                press_slopes(geometry, c.centre_px, c.radius_px, s);
                let mut n = Normal::new(NORMAL_TERMS.len());
                n.add(s, input.image_size);
                Some(n)
            })
            .collect();
        solve_cross_validated(&normals)
    };
    let mut best: Option<(f64, Geometry)> = None;
    for &contact_ratio in &CONTACT_RATIOS {
        for &spread_mm in &SPREADS_MM {
            let geometry = Geometry { pitch, ball, contact_ratio, spread: spread_mm * 1e-3 };
            let Some(solved) = solve_at(geometry, &presses, &mut samples) else { continue };
            if best.is_none_or(|(b, _)| solved.cross_validated < b) {
                best = Some((solved.cross_validated, geometry));
            }
        }
    }
    let (_, mut geometry) =
        best.ok_or_else(|| anyhow::anyhow!("too few contact pixels to fit the light model: press deeper, or more presses"))?;
    // Then each refined between its grid neighbours by golden sections.
    let mut cost = |g: Geometry| solve_at(g, &presses, &mut samples).map_or(f64::INFINITY, |s| s.cross_validated);
    let spread =
        golden(|s| cost(Geometry { spread: s.max(0.0), ..geometry }), (geometry.spread - 0.25e-3).max(0.0), geometry.spread + 0.25e-3, 8);
    geometry.spread = spread.max(0.0);
    let ratio = golden(
        |k| cost(Geometry { contact_ratio: k, ..geometry }),
        geometry.contact_ratio - 0.1,
        (geometry.contact_ratio + 0.1).min(1.0),
        8,
    );
    geometry.contact_ratio = ratio;
    anyhow::ensure!(
        samples.iter().map(Vec::len).sum::<usize>() >= 200,
        "only {} contact pixels over the presses: press deeper, or more presses",
        samples.iter().map(Vec::len).sum::<usize>()
    );

    // Centres refined against the model; presses that do not fit the others rejected; refit.
    let mut solved = solve_at(geometry, &presses, &mut samples).expect("solved above");
    let mut coefficients = solved.coefficients.clone();
    for round in 0..2 {
        for (k, p) in presses.iter_mut().enumerate() {
            let Some(c) = p.contact.as_mut().filter(|_| p.rejected.is_none()) else { continue };
            c.centre_px = refine_centre(geometry, c, &mut samples[k], &coefficients, input.image_size);
        }
        solved = solve_at(geometry, &presses, &mut samples).expect("solved above");
        coefficients = solved.coefficients.clone();
        let rms: Vec<f64> = presses
            .iter()
            .zip(&samples)
            .map(|(p, s)| if p.rejected.is_none() { rms_of(s, &coefficients, input.image_size) } else { 0.0 })
            .collect();
        let mut kept: Vec<f64> = presses.iter().zip(&rms).filter(|(p, _)| p.rejected.is_none()).map(|(_, r)| *r).collect();
        kept.sort_by(f64::total_cmp);
        let median = kept[kept.len() / 2];
        let mut rejected_any = false;
        if round == 0 && kept.len() > 3 {
            for (p, r) in presses.iter_mut().zip(&rms) {
                if p.rejected.is_none() && *r > (2.0 * median).max(median + 4.0) {
                    p.rejected =
                        Some(format!("does not fit the others ({r:.1} levels RMS, their median {median:.1}): a misdetected contact?"));
                    rejected_any = true;
                }
            }
        }
        if rejected_any {
            solved = solve_at(geometry, &presses, &mut samples).expect("solved above");
            coefficients = solved.coefficients.clone();
        }
    }
    let coefficients: [Vec<f64>; 3] = std::array::from_fn(|c| coefficients[c].clone());
    let fitted: Vec<(&Sample, usize)> = presses
        .iter()
        .zip(&samples)
        .enumerate()
        .filter(|(_, (p, _))| p.rejected.is_none())
        .flat_map(|(k, (_, s))| s.iter().map(move |q| (q, k)))
        .collect();
    let leds = fit_leds(input, &fitted, pitch, &coefficients);

    // Residuals per press and model.
    let sensor = led_sensor(input.image_size, pitch, &leds);
    let [w, _] = input.image_size;
    let background = &input.background.rgb;
    let (mut sq_poly, mut sq_leds, mut count) = (0.0, 0.0, 0usize);
    for (k, press) in presses.iter_mut().enumerate() {
        if let Some(c) = &press.contact {
            press.depth_mm = geometry.depth(c.radius_px) * 1e3;
        }
        if press.rejected.is_some() {
            continue;
        }
        let (mut sp, mut sl, mut n) = (0.0, 0.0, 0usize);
        for s in &samples[k] {
            let at = position(input.image_size, s.u, s.v);
            let poly = polynomial_delta(&coefficients, at, s.slope);
            let led = led_image(&sensor, at, Some(s.slope));
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
        pixel_size_source,
        elastic_spread_mm: geometry.spread * 1e3,
        contact_ratio: geometry.contact_ratio,
        position_terms: solved.position_terms,
        rms_cross_validated: 255.0 * solved.cross_validated.sqrt(),
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
            elastic_spread_mm: Some(self.elastic_spread_mm),
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

    /// The calibrated sensor (noise-free, no markers) with the unit's background image: what
    /// `robot.tactile.optical.calibration` makes of this fit's file.
    pub fn sensor(&self, image_size: [u32; 2], background: &CalibrationImage) -> OpticalSensor {
        let mut s = crate::config::OpticalPreset::GelsightMini.sensor();
        s.image_size = image_size;
        s.sensing_area_mm = image_size.map(|n| n as f64 * self.pixel_size_mm);
        s.elastic_spread_mm = self.elastic_spread_mm;
        s.noise_std = 0.0;
        s.markers = None;
        if self.chosen == "polynomial" {
            let loaded = LoadedCalibration {
                image_size,
                pixel_size_mm: Some(self.pixel_size_mm),
                elastic_spread_mm: Some(self.elastic_spread_mm),
                background: Some(background.rgb.clone()),
                light: Some(LightModel::Polynomial { coefficients: self.coefficients.clone() }),
                leds: None,
            };
            s.calibration =
                Some(SensorCalibration { file: String::new(), model: "polynomial".into(), light: Some(std::sync::Arc::new(loaded)) });
        } else {
            s.lights = self.leds.lights.clone();
            s.ambient = self.leds.ambient;
            s.background = self.leds.background;
            s.vignetting = self.leds.vignetting;
        }
        s
    }
}

/// A press rendered through a calibrated sensor against the real frame.
#[derive(Debug, Clone)]
pub struct PressComparison {
    /// The press as rendered: its centre (pixels) and depth (mm).
    pub centre_px: [f64; 2],
    pub depth_mm: f64,
    /// Pixels compared: the visible contact disc without markers.
    pub pixels: usize,
    /// RMS (8-bit levels) of the rendered press against the real frame over the disc.
    pub rms_rendered: f64,
    /// RMS of the background against the real frame over the disc ("no change").
    pub rms_no_change: f64,
}

/// Renders a ball press where `contact` says the real one was (its centre; its depth from the
/// visible radius at the fit's contact ratio) through `sensor`, and compares it with the real
/// frame over the whole visible disc. The sensor's gel is made thick enough for the press.
pub fn compare_press(
    prepared: &Prepared,
    sensor: &OpticalSensor,
    press: &CalibrationImage,
    contact: &Contact,
    ball_radius_mm: f64,
    contact_ratio: f64,
) -> PressComparison {
    let input = prepared.input;
    let pitch = sensor.sensing_area_mm[0] * 1e-3 / sensor.image_size[0] as f64;
    let geometry = Geometry { pitch, ball: ball_radius_mm * 1e-3, contact_ratio, spread: sensor.elastic_spread_mm * 1e-3 };
    let depth = geometry.depth(contact.radius_px);
    let rendered = render_press(sensor, ball_radius_mm, depth * 1e3, contact.centre_px);
    let mut pixels_compared = 0usize;
    let (mut sq_r, mut sq_b) = (0.0, 0.0);
    for s in prepared.disc_samples(press, contact) {
        let k = (s.v * input.image_size[0] + s.u) as usize * 3;
        for c in 0..3 {
            let real = 255.0 * press.rgb[k + c];
            sq_r += (rendered.rgb[k + c] as f64 - real).powi(2);
            sq_b += (255.0 * input.background.rgb[k + c] - real).powi(2);
        }
        pixels_compared += 1;
    }
    let n = (3 * pixels_compared).max(1) as f64;
    PressComparison {
        centre_px: contact.centre_px,
        depth_mm: depth * 1e3,
        pixels: pixels_compared,
        rms_rendered: (sq_r / n).sqrt(),
        rms_no_change: (sq_b / n).sqrt(),
    }
}

/// The image of a ball of `ball_radius_mm` pressed `depth_mm` into the gel with its centre over
/// pixel position `centre_px` (column, row from the image's corner), noise-free, through `sensor`.
/// The sensor's gel is made at least twice as thick as the press, so the press is never cut off.
pub fn render_press(sensor: &OpticalSensor, ball_radius_mm: f64, depth_mm: f64, centre_px: [f64; 2]) -> super::optical::OpticalImage {
    let mut s = sensor.clone();
    s.gel_thickness_mm = s.gel_thickness_mm.max(2.0 * depth_mm);
    let [w, h] = s.image_size;
    let (px, py) = (s.sensing_area_mm[0] * 1e-3 / w as f64, s.sensing_area_mm[1] * 1e-3 / h as f64);
    let centre = [(centre_px[0] - w as f64 / 2.0) * px, (centre_px[1] - h as f64 / 2.0) * py];
    let depth = ball_press_depth(&s, ball_radius_mm * 1e-3, depth_mm * 1e-3, centre);
    super::optical::optical_image(&s, Some(&depth), None, None)
}

/// Image position (-1..=1) of pixel (u, v)'s centre, as `optical::pixel_position`.
fn position([w, h]: [u32; 2], u: u32, v: u32) -> [f64; 2] {
    [(2.0 * u as f64 + 1.0) / w as f64 - 1.0, (2.0 * v as f64 + 1.0) / h as f64 - 1.0]
}

/// The sphere's slopes at a sample for a press centred at `centre` (pixels): `-(x - cx) /
/// sqrt(r^2 - d^2)`; flat outside 0.98 of the ball.
fn sphere_slope(s: &Sample, centre: [f64; 2], geometry: Geometry) -> (f64, f64) {
    let (dx, dy) = ((s.u as f64 + 0.5 - centre[0]) * geometry.pitch, (s.v as f64 + 0.5 - centre[1]) * geometry.pitch);
    let z2 = geometry.ball.powi(2) - dx * dx - dy * dy;
    if z2 > (0.2 * geometry.ball).powi(2) { (-dx / z2.sqrt(), -dy / z2.sqrt()) } else { (0.0, 0.0) }
}

/// The lighting's drift `[1, x, y, x^2, x y, y^2]` at image position `at`, per channel.
fn drift_at(drift: &[[f64; 6]; 3], [x, y]: [f64; 2]) -> [f64; 3] {
    let t = [1.0, x, y, x * x, x * y, y * y];
    std::array::from_fn(|c| drift[c].iter().zip(&t).map(|(a, b)| a * b).sum())
}

/// The lighting's drift from the background to a press: per channel, a quadratic surface fitted
/// to their difference over a grid of unmasked pixels, its outliers (the contact) trimmed three
/// times at three robust standard deviations.
fn fit_drift(input: &CalibrationInput, press: &CalibrationImage, mask: &[bool]) -> [[f64; 6]; 3] {
    let [w, h] = input.image_size;
    let step = ((w.min(h) / 60).max(1)) as usize;
    let points: Vec<([f64; 6], [f64; 3])> = (0..h)
        .step_by(step)
        .flat_map(|v| (0..w).step_by(step).map(move |u| (u, v)))
        .filter(|&(u, v)| !mask[(v * w + u) as usize])
        .map(|(u, v)| {
            let [x, y] = position(input.image_size, u, v);
            let k = (v * w + u) as usize * 3;
            ([1.0, x, y, x * x, x * y, y * y], std::array::from_fn(|c| press.rgb[k + c] - input.background.rgb[k + c]))
        })
        .collect();
    let mut drift = [[0.0; 6]; 3];
    for (c, d) in drift.iter_mut().enumerate() {
        let mut keep = vec![true; points.len()];
        for _ in 0..4 {
            let mut ata = DMatrix::<f64>::zeros(6, 6);
            let mut atb = DVector::<f64>::zeros(6);
            for ((t, y), _) in points.iter().zip(&keep).filter(|(_, k)| **k) {
                for a in 0..6 {
                    for b in 0..6 {
                        ata[(a, b)] += t[a] * t[b];
                    }
                    atb[a] += t[a] * y[c];
                }
            }
            let Some(x) = ata.clone().cholesky().map(|ch| ch.solve(&atb)) else { break };
            d.copy_from_slice(x.as_slice());
            let residual: Vec<f64> =
                points.iter().map(|(t, y)| (y[c] - t.iter().zip(d.iter()).map(|(a, b)| a * b).sum::<f64>()).abs()).collect();
            let mut sorted = residual.clone();
            let mid = sorted.len() / 2;
            sorted.select_nth_unstable_by(mid, f64::total_cmp);
            let limit = (3.0 * 1.4826 * sorted[mid]).max(1.5 / 255.0);
            keep = residual.iter().map(|r| *r <= limit).collect();
        }
    }
    drift
}

/// A box blur of radius `r` (pixels) with edges clamped.
fn box_blur(img: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let pass = |src: &[f64], w: usize, h: usize| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..h {
            let row = &src[y * w..(y + 1) * w];
            let mut prefix = vec![0.0; w + 1];
            for x in 0..w {
                prefix[x + 1] = prefix[x] + row[x];
            }
            for x in 0..w {
                let (a, b) = (x.saturating_sub(r), (x + r + 1).min(w));
                out[y * w + x] = (prefix[b] - prefix[a]) / (b - a) as f64;
            }
        }
        out
    };
    let transpose = |src: &[f64], w: usize, h: usize| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..h {
            for x in 0..w {
                out[x * h + y] = src[y * w + x];
            }
        }
        out
    };
    let rows = pass(img, w, h);
    transpose(&pass(&transpose(&rows, w, h), h, w), h, w)
}

/// A mask's opening: eroded by `r` pixels, then grown back by `r` (square neighbourhoods).
fn open_mask(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let as_f: Vec<f64> = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
    let eroded: Vec<bool> = box_blur(&as_f, w, h, r).into_iter().map(|v| v > 1.0 - 1e-9).collect();
    dilate(&eroded, w, h, r)
}

/// A mask grown by `r` pixels (square neighbourhood).
fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let as_f: Vec<f64> = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
    box_blur(&as_f, w, h, r).into_iter().map(|v| v > 0.0).collect()
}

/// The largest 8-connected component of `on`: its pixels and size.
fn largest_component(on: &[bool], w: usize, h: usize) -> (Vec<usize>, usize) {
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
    ((0..w * h).filter(|&k| best_size > 0 && label[k] == best).collect(), best_size)
}

/// A circle through outline points (Kåsa's fit), refitted twice without the points farther than
/// 2.5 robust deviations from it: (centre, radius, the points' median distance from it / radius).
fn robust_circle(points: &[[f64; 2]]) -> Option<([f64; 2], f64, f64)> {
    let mut keep: Vec<[f64; 2]> = points.to_vec();
    let mut circle = None;
    for _ in 0..3 {
        if keep.len() < 3 {
            return None;
        }
        let mut a = DMatrix::<f64>::zeros(keep.len(), 3);
        let mut b = DVector::<f64>::zeros(keep.len());
        for (i, p) in keep.iter().enumerate() {
            a[(i, 0)] = p[0];
            a[(i, 1)] = p[1];
            a[(i, 2)] = 1.0;
            b[i] = -(p[0] * p[0] + p[1] * p[1]);
        }
        let x = (a.transpose() * &a).lu().solve(&(a.transpose() * b))?;
        let centre = [-x[0] / 2.0, -x[1] / 2.0];
        let radius = (centre[0] * centre[0] + centre[1] * centre[1] - x[2]).max(0.0).sqrt();
        let off: Vec<f64> = points.iter().map(|p| ((p[0] - centre[0]).hypot(p[1] - centre[1]) - radius).abs()).collect();
        let mut sorted = off.clone();
        sorted.sort_by(f64::total_cmp);
        let limit = (2.5 * 1.4826 * sorted[sorted.len() / 2]).max(1.0);
        let kept: Vec<[f64; 2]> = points.iter().zip(&off).filter(|(_, o)| **o <= limit).map(|(p, _)| *p).collect();
        // Robust: a few stray points (moved markers along the rim) do not make an outline not
        // round; a crescent's or two contacts' half of the points do.
        let median = sorted[sorted.len() / 2];
        circle = Some((centre, radius, median / radius.max(1e-9)));
        keep = kept;
    }
    circle
}

/// Normal equations of the polynomial model with the first `normal_terms` normal terms (3: the
/// LED model's linear form; 6: the full polynomial), accumulated sample by sample.
struct Normal {
    terms: usize,
    ata: DMatrix<f64>,
    atb: [DVector<f64>; 3],
    btb: f64,
    count: usize,
}

impl Normal {
    fn new(normal_terms_used: usize) -> Self {
        let k = normal_terms_used * POSITION_TERMS.len();
        Normal { terms: normal_terms_used, ata: DMatrix::zeros(k, k), atb: std::array::from_fn(|_| DVector::zeros(k)), btb: 0.0, count: 0 }
    }

    fn add(&mut self, samples: &[Sample], size: [u32; 2]) {
        let np = POSITION_TERMS.len();
        let k = self.terms * np;
        let mut row = vec![0.0; k];
        for s in samples {
            let (n, p) = (normal_terms(s.slope), position_terms(position(size, s.u, s.v)));
            for j in 0..self.terms {
                for (i, pi) in p.iter().enumerate() {
                    row[j * np + i] = n[j] * pi;
                }
            }
            // Rank-one update (upper triangle, mirrored in `solve`).
            for a in 0..k {
                let ra = row[a];
                if ra == 0.0 {
                    continue;
                }
                for (b, rb) in row.iter().enumerate().skip(a) {
                    self.ata[(a, b)] += ra * rb;
                }
                for c in 0..3 {
                    self.atb[c][a] += ra * s.delta[c];
                }
            }
            self.btb += s.delta.iter().map(|d| d * d).sum::<f64>();
            self.count += 1;
        }
    }

    fn clone_full(&self) -> Normal {
        Normal { terms: self.terms, ata: self.ata.clone(), atb: self.atb.clone(), btb: self.btb, count: self.count }
    }

    /// Adds (`sign` 1) or removes (-1) another press's equations.
    fn merge(&mut self, other: &Normal, sign: f64) {
        self.ata += &other.ata * sign;
        for c in 0..3 {
            self.atb[c] += &other.atb[c] * sign;
        }
        self.btb += sign * other.btb;
        self.count = if sign > 0.0 { self.count + other.count } else { self.count - other.count };
    }

    /// The symmetric system restricted to the terms `idx`.
    fn subset(&self, idx: &[usize]) -> (DMatrix<f64>, [DVector<f64>; 3]) {
        let k = idx.len();
        let ata = DMatrix::from_fn(k, k, |a, b| {
            let (i, j) = (idx[a].min(idx[b]), idx[a].max(idx[b]));
            self.ata[(i, j)]
        });
        (ata, std::array::from_fn(|c| DVector::from_fn(k, |a, _| self.atb[c][idx[a]])))
    }

    /// Least squares over the terms `idx` (a tiny ridge keeps unused terms at zero).
    fn solve_subset(&self, idx: &[usize]) -> Option<[DVector<f64>; 3]> {
        if self.count < idx.len() {
            return None;
        }
        let (mut ata, atb) = self.subset(idx);
        let k = idx.len();
        let ridge = 1e-9 * (0..k).map(|a| ata[(a, a)]).sum::<f64>() / k as f64 + 1e-12;
        for a in 0..k {
            ata[(a, a)] += ridge;
        }
        let chol = ata.cholesky()?;
        Some(std::array::from_fn(|c| chol.solve(&atb[c])))
    }

    /// The sum of squared residuals of `x` (over the terms `idx`) on these equations.
    fn residual_subset(&self, idx: &[usize], x: &[DVector<f64>; 3]) -> f64 {
        let (ata, atb) = self.subset(idx);
        let sq: f64 = (0..3).map(|c| (x[c].transpose() * &ata * &x[c])[(0, 0)] - 2.0 * x[c].dot(&atb[c])).sum::<f64>() + self.btb;
        sq.max(0.0)
    }

    /// The coefficients per channel (zero-padded to the full model) and the mean squared residual.
    fn solve(&self) -> Option<([Vec<f64>; 3], f64)> {
        let k = self.ata.nrows();
        if self.count < k {
            return None;
        }
        let mut ata = self.ata.clone();
        for a in 0..k {
            for b in 0..a {
                ata[(a, b)] = ata[(b, a)];
            }
        }
        let ridge = 1e-10 * (0..k).map(|a| ata[(a, a)]).sum::<f64>() / k as f64;
        let plain = ata.clone();
        for a in 0..k {
            ata[(a, a)] += ridge;
        }
        let chol = ata.cholesky()?;
        let x: [DVector<f64>; 3] = std::array::from_fn(|c| chol.solve(&self.atb[c]));
        // |Ax - b|^2 = x'A'Ax - 2 x'A'b + b'b.
        let sq: f64 = (0..3).map(|c| (x[c].transpose() * &plain * &x[c])[(0, 0)] - 2.0 * x[c].dot(&self.atb[c])).sum::<f64>() + self.btb;
        let full = NORMAL_TERMS.len() * POSITION_TERMS.len();
        let coefficients = std::array::from_fn(|c| {
            let mut v = vec![0.0; full];
            v[..k].copy_from_slice(x[c].as_slice());
            v
        });
        Some((coefficients, sq.max(0.0) / (3 * self.count) as f64))
    }
}

/// A polynomial fit: its coefficients (per channel, zero-padded to the full model), how many
/// image-position terms it uses and its mean squared residual over presses left out in turn.
struct Solved {
    coefficients: [Vec<f64>; 3],
    position_terms: usize,
    cross_validated: f64,
}

/// The full polynomial fitted to per-press normal equations, with the image-position degree
/// (constant, linear, quadratic, cubic) whose leave-one-press-out residual is smallest; with
/// fewer than three presses, the constant.
fn solve_cross_validated(normals: &[Normal]) -> Option<Solved> {
    let mut total = Normal::new(NORMAL_TERMS.len());
    for n in normals {
        total.merge(n, 1.0);
    }
    let np = POSITION_TERMS.len();
    let keep = |position_terms: usize| -> Vec<usize> {
        (0..NORMAL_TERMS.len()).flat_map(|j| (0..position_terms).map(move |i| j * np + i)).collect()
    };
    let mut best: Option<(f64, usize)> = None;
    for position_terms in [1, 3, 6, 10] {
        let idx = keep(position_terms);
        let mse = if normals.len() >= 3 {
            let (mut sq, mut count) = (0.0, 0usize);
            for n in normals {
                let mut rest = total.clone_full();
                rest.merge(n, -1.0);
                let Some(x) = rest.solve_subset(&idx) else {
                    sq = f64::INFINITY;
                    break;
                };
                sq += n.residual_subset(&idx, &x);
                count += 3 * n.count;
            }
            sq / count.max(1) as f64
        } else if position_terms == 1 {
            let x = total.solve_subset(&idx)?;
            total.residual_subset(&idx, &x) / (3 * total.count).max(1) as f64
        } else {
            continue;
        };
        if best.is_none_or(|(b, _)| mse < b) {
            best = Some((mse, position_terms));
        }
    }
    let (cross_validated, position_terms) = best?;
    let idx = keep(position_terms);
    let x = total.solve_subset(&idx)?;
    let full = NORMAL_TERMS.len() * np;
    let coefficients = std::array::from_fn(|c| {
        let mut v = vec![0.0; full];
        for (k, &i) in idx.iter().enumerate() {
            v[i] = x[c][k];
        }
        v
    });
    Some(Solved { coefficients, position_terms, cross_validated })
}

/// RMS (8-bit levels) of the polynomial model over samples.
fn rms_of(samples: &[Sample], coefficients: &[Vec<f64>; 3], size: [u32; 2]) -> f64 {
    let sq: f64 = samples
        .iter()
        .map(|s| {
            let m = polynomial_delta(coefficients, position(size, s.u, s.v), s.slope);
            (0..3).map(|c| (m[c] - s.delta[c]).powi(2)).sum::<f64>()
        })
        .sum();
    255.0 * (sq / (3 * samples.len()).max(1) as f64).sqrt()
}

/// A press's centre moved (within ±1.5 px) to where the model, held fixed, fits its pixels best.
fn refine_centre(geometry: Geometry, contact: &Contact, samples: &mut [Sample], coefficients: &[Vec<f64>; 3], size: [u32; 2]) -> [f64; 2] {
    let origin = contact.centre_px;
    let mut evaluate = |c: [f64; 2]| {
        press_slopes(geometry, c, contact.radius_px, samples);
        rms_of(samples, coefficients, size)
    };
    let mut best = (evaluate(origin), origin);
    for step in [0.5, 0.2, 0.05] {
        let around = best.1;
        for (dx, dy) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (-1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (1.0, -1.0)] {
            let c = [around[0] + dx * step, around[1] + dy * step];
            if (c[0] - origin[0]).abs() > 1.5 || (c[1] - origin[1]).abs() > 1.5 {
                continue;
            }
            let e = evaluate(c);
            if e < best.0 {
                best = (e, c);
            }
        }
    }
    press_slopes(geometry, best.1, contact.radius_px, samples);
    best.1
}

/// The minimum of a unimodal `f` on `[a, b]` by golden sections.
fn golden(mut f: impl FnMut(f64) -> f64, mut a: f64, mut b: f64, iterations: usize) -> f64 {
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
/// pixels (`(sample, press)`) and a grid of background pixels.
fn fit_leds(input: &CalibrationInput, samples: &[(&Sample, usize)], pitch: f64, coefficients: &[Vec<f64>; 3]) -> LedFit {
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
        .map(|(s, _)| {
            let base = (s.v * w + s.u) as usize * 3;
            (s.u, s.v, Some(s.slope), std::array::from_fn(|c| input.background.rgb[base + c] + s.delta[c]))
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
        let geometry = Geometry { pitch: 1e-4, ball: 2e-3, contact_ratio: 1.0, spread: 0.0 };
        let at = |u| Sample { u, v: 5, delta: [0.0; 3], slope: (0.0, 0.0) };
        let (gx, gy) = sphere_slope(&at(10), [5.5, 5.5], geometry);
        assert!(gx < 0.0 && gy.abs() < 1e-12, "{gx} {gy}");
        let (steeper, _) = sphere_slope(&at(20), [5.5, 5.5], geometry);
        assert!(steeper < gx);
        assert_eq!(sphere_slope(&at(40), [5.5, 5.5], geometry), (0.0, 0.0), "outside the ball");
    }

    /// vtgen's gel model over a press window gives the sphere's slopes inside the contact.
    #[test]
    fn a_press_window_has_the_balls_slopes_inside_its_contact() {
        let geometry = Geometry { pitch: 1e-4, ball: 2e-3, contact_ratio: 1.0, spread: 0.3e-3 };
        let mut samples: Vec<Sample> = (30..50).map(|u| Sample { u, v: 40, delta: [0.0; 3], slope: (0.0, 0.0) }).collect();
        press_slopes(geometry, [40.0, 40.5], 12.0, &mut samples);
        for s in samples.iter().filter(|s| (s.u as f64 + 0.5 - 40.0).abs() < 10.0) {
            let want = sphere_slope(s, [40.0, 40.5], geometry);
            assert!((s.slope.0 - want.0).abs() < 0.03 && s.slope.1.abs() < 1e-9, "u {}: {:?} vs {want:?}", s.u, s.slope);
        }
    }

    #[test]
    fn golden_sections_find_a_minimum() {
        let x = golden(|x| (x - 0.37).powi(2), 0.0, 1.0, 60);
        assert!((x - 0.37).abs() < 1e-6, "{x}");
    }

    /// Kåsa's circle with outliers trimmed recovers a circle from an outline with a few strays.
    #[test]
    fn a_robust_circle_ignores_stray_outline_points() {
        let mut points: Vec<[f64; 2]> =
            (0..90).map(|k| (k as f64).to_radians() * 4.0).map(|t| [30.0 + 12.0 * t.cos(), 20.0 + 12.0 * t.sin()]).collect();
        points.extend([[30.0, 20.0], [31.0, 22.0], [29.0, 19.0]]);
        let (c, r, _) = robust_circle(&points).unwrap();
        assert!((c[0] - 30.0).abs() < 0.05 && (c[1] - 20.0).abs() < 0.05 && (r - 12.0).abs() < 0.05, "{c:?} {r}");
    }
}
