//! `vtgen tactile calibrate DIR --ball-radius R`: an optical sensor fitted to a real unit's images
//! (`sensors::optical_fit`), written as a calibration `robot.tactile.optical.calibration` takes;
//! `vtgen tactile render-press`: a press rendered through any calibration, to set beside a real frame.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::config::OpticalConfig;
use crate::config::optical_calibration::{load_calibration, parse_npy};
use crate::sensors::optical::optical_image_of_surface;
use crate::sensors::optical_fit::{CalibrationImage, CalibrationInput, Prepared, compare_press, fit, marker_period_px, render_press};

/// The image files of a calibration folder, by name: the background, then the presses.
fn calibration_images(dir: &Path) -> Result<(PathBuf, Vec<PathBuf>)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .filter(|p| {
            p.extension().and_then(|e| e.to_str()).is_some_and(|e| ["png", "jpg", "jpeg", "bmp"].contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    files.sort();
    let is_background = |p: &PathBuf| p.file_stem().and_then(|s| s.to_str()).is_some_and(|s| matches!(s, "background" | "bg"));
    let backgrounds: Vec<PathBuf> = files.iter().filter(|p| is_background(p)).cloned().collect();
    let background = match backgrounds.as_slice() {
        [one] => one.clone(),
        [] => bail!(
            "{}: no background image: name the image with nothing touching the gel background.png (or bg.png); found {}",
            dir.display(),
            if files.is_empty() {
                "no images".to_string()
            } else {
                files.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
            }
        ),
        more => bail!(
            "{}: {} background images ({}): keep one",
            dir.display(),
            more.len(),
            more.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        ),
    };
    let presses: Vec<PathBuf> = files.into_iter().filter(|p| !is_background(p)).collect();
    if presses.len() < 2 {
        bail!(
            "{}: {} press image(s): the fit needs at least 2 presses of the ball at different places (Taxim's recipe uses dozens)",
            dir.display(),
            presses.len()
        );
    }
    Ok((background, presses))
}

fn read_image(path: &Path, size: Option<[u32; 2]>) -> Result<CalibrationImage> {
    let img = image::open(path).with_context(|| format!("cannot read {}", path.display()))?.to_rgb8();
    if let Some([w, h]) = size
        && img.dimensions() != (w, h)
    {
        bail!(
            "{}: {} x {} pixels, the background is {w} x {h}: every image must be the same size",
            path.display(),
            img.width(),
            img.height()
        );
    }
    let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    Ok(CalibrationImage { name, rgb: img.into_raw().into_iter().map(|b| b as f64 / 255.0).collect() })
}

/// Which presses `--holdout K` keeps out of the fit: K spread evenly over the sorted names.
fn held_out_indices(presses: usize, k: usize) -> Vec<usize> {
    let mut out: Vec<usize> = (0..k).map(|i| (((i as f64 + 0.5) * presses as f64 / k as f64) as usize).min(presses - 1)).collect();
    out.dedup();
    out
}

/// Fits, writes `OUT/calibration.yaml` (+ `OUT/background.png` for the polynomial model) and prints
/// the report; with `holdout` presses kept out of the fit, rendered through it and compared with
/// their real frames.
pub fn calibrate(
    dir: &Path,
    ball_radius_mm: f64,
    pixel_size_mm: Option<f64>,
    marker_pitch_mm: Option<f64>,
    holdout: usize,
    out: &Path,
) -> Result<()> {
    if !(ball_radius_mm > 0.0 && ball_radius_mm < 100.0) {
        bail!("--ball-radius {ball_radius_mm}: the ball's radius in mm, 0 < r < 100");
    }
    if let Some(p) = pixel_size_mm.filter(|p| !(*p > 0.0 && *p < 10.0)) {
        bail!("--pixel-size-mm {p}: allowed 0 < size < 10 mm");
    }
    let (background_path, press_paths) = calibration_images(dir)?;
    if holdout > 0 && press_paths.len() < holdout + 2 {
        bail!("--holdout {holdout}: {} presses leave fewer than 2 to fit", press_paths.len());
    }
    let background = read_image(&background_path, None)?;
    let dims = image::image_dimensions(&background_path)?;
    let size = [dims.0, dims.1];
    // The printed markers as the known-size target: their pitch in mm over their period in pixels.
    let pixel_size_mm = match marker_pitch_mm {
        None => pixel_size_mm,
        Some(p) if !(p > 0.0 && p < 100.0) => bail!("--marker-pitch-mm {p}: allowed 0 < pitch < 100 mm"),
        Some(pitch) => {
            let [px, py] = marker_period_px(&background, size)
                .map_err(|e| anyhow::anyhow!("{}: --marker-pitch-mm: {e}", background_path.display()))?;
            if (px - py).abs() > 0.05 * px.max(py) {
                bail!(
                    "{}: the markers repeat every {px:.2} pixels across and {py:.2} down: pixels this far from square (or a grid \
                     this far from square) cannot give one pixel size; give --pixel-size-mm",
                    background_path.display()
                );
            }
            let size_mm = pitch / (0.5 * (px + py));
            println!("pixel size from the markers: {pitch} mm every {px:.2} x {py:.2} pixels = {size_mm:.5} mm");
            Some(size_mm)
        }
    };
    let all = press_paths.iter().map(|p| read_image(p, Some(size))).collect::<Result<Vec<_>>>()?;
    let held = if holdout > 0 { held_out_indices(all.len(), holdout) } else { Vec::new() };
    let (held_images, presses): (Vec<_>, Vec<_>) = all.into_iter().enumerate().partition(|(k, _)| held.contains(k));
    let presses: Vec<CalibrationImage> = presses.into_iter().map(|(_, p)| p).collect();
    let held_images: Vec<CalibrationImage> = held_images.into_iter().map(|(_, p)| p).collect();
    eprintln!(
        "vtgen: fitting {} presses ({} x {} pixels) of a {ball_radius_mm} mm ball{}",
        presses.len(),
        size[0],
        size[1],
        if held_images.is_empty() { String::new() } else { format!(", {} held out", held_images.len()) }
    );
    let input = CalibrationInput { image_size: size, background: &background, presses: &presses, ball_radius_mm, pixel_size_mm };
    let fitted = fit(&input)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let file = fitted.file(size, "background.png");
    if fitted.chosen == "polynomial" {
        let bg: Vec<u8> = background.rgb.iter().map(|v| (v * 255.0).round() as u8).collect();
        let png = out.join("background.png");
        image::RgbImage::from_raw(size[0], size[1], bg)
            .context("background size")?
            .save(&png)
            .with_context(|| format!("cannot write {}", png.display()))?;
    }
    let yaml = out.join("calibration.yaml");
    // The path a config takes as it is, wherever the config lives.
    let absolute = std::path::absolute(&yaml).unwrap_or_else(|_| yaml.clone());
    let header = format!(
        "# An optical sensor fitted by `vtgen tactile calibrate` to {} ({} presses of a {ball_radius_mm} mm ball{}).\n\
         # Use it as robot.tactile.optical.calibration: {}\n\
         # Residual over the presses' contacts (8-bit levels RMS): polynomial {:.2}, leds {:.2}; kept: {}.\n",
        dir.display(),
        presses.len(),
        if held_images.is_empty() { String::new() } else { format!("; {} more held out", held_images.len()) },
        absolute.display(),
        fitted.rms_polynomial,
        fitted.rms_leds,
        fitted.chosen
    );
    std::fs::write(&yaml, header + &serde_yaml::to_string(&file)?).with_context(|| format!("cannot write {}", yaml.display()))?;
    println!("pixel size: {:.4} mm ({})", fitted.pixel_size_mm, fitted.pixel_size_source);
    println!("gel: contact radius {:.2} of the visible one, elastic spread {:.2} mm", fitted.contact_ratio, fitted.elastic_spread_mm);
    println!(
        "light model: {} (RMS over the contact discs: polynomial {:.2} levels, leds {:.2} levels; the polynomial's image-position \
         terms: {} of 10, {:.2} levels RMS on each press left out of it in turn)",
        fitted.chosen, fitted.rms_polynomial, fitted.rms_leds, fitted.position_terms, fitted.rms_cross_validated
    );
    println!(
        "{:<28} {:>9} {:>9} {:>8} {:>8} {:>8} {:>11} {:>11}",
        "image", "centre u", "centre v", "radius", "depth", "pixels", "polynomial", "leds"
    );
    for p in fitted.presses.iter().filter(|p| p.rejected.is_none()) {
        let c = p.contact.as_ref().expect("a used press has a contact");
        println!(
            "{:<28} {:>9.2} {:>9.2} {:>8.1} {:>8.3} {:>8} {:>11.2} {:>11.2}",
            p.name, c.centre_px[0], c.centre_px[1], c.radius_px, p.depth_mm, p.pixels, p.rms_polynomial, p.rms_leds
        );
    }
    println!("(radius: visible, pixels; depth: mm, from the contact radius; residuals: RMS in 8-bit levels over the visible disc)");
    let rejected: Vec<&_> = fitted.presses.iter().filter(|p| p.rejected.is_some()).collect();
    if !rejected.is_empty() {
        println!("left out of the fit ({}):", rejected.len());
        for p in rejected {
            println!("  {}: {}", p.name, p.rejected.as_deref().unwrap_or_default());
        }
    }
    if !held_images.is_empty() {
        let sensor = fitted.sensor(size, &background);
        let prepared = Prepared::new(&input);
        println!("held out ({}), rendered through the calibration at their detected centre and depth:", held_images.len());
        println!(
            "{:<28} {:>9} {:>9} {:>8} {:>8} {:>8} {:>10} {:>10}",
            "image", "centre u", "centre v", "radius", "depth", "pixels", "rendered", "no change"
        );
        let (mut sq_r, mut sq_b, mut n) = (0.0, 0.0, 0usize);
        for img in &held_images {
            match prepared.detect(img) {
                Ok(contact) => {
                    let c = compare_press(&prepared, &sensor, img, &contact, ball_radius_mm, fitted.contact_ratio);
                    println!(
                        "{:<28} {:>9.2} {:>9.2} {:>8.1} {:>8.3} {:>8} {:>10.2} {:>10.2}",
                        img.name, c.centre_px[0], c.centre_px[1], contact.radius_px, c.depth_mm, c.pixels, c.rms_rendered, c.rms_no_change
                    );
                    sq_r += c.rms_rendered.powi(2) * c.pixels as f64;
                    sq_b += c.rms_no_change.powi(2) * c.pixels as f64;
                    n += c.pixels;
                }
                Err(e) => println!("{:<28} not compared: {e}", img.name),
            }
        }
        if n > 0 {
            println!(
                "held-out RMS over the whole contact discs: {:.2} levels rendered, {:.2} levels no change ({n} pixels)",
                (sq_r / n as f64).sqrt(),
                (sq_b / n as f64).sqrt()
            );
        }
    }
    println!("fitted in {:.2} s; wrote {}", fitted.seconds, yaml.display());
    Ok(())
}

/// What `render-press` renders: a ball press, or a height map of the gel's surface.
pub enum PressShape {
    Ball {
        radius_mm: f64,
        depth_mm: f64,
        centre_px: Option<[f64; 2]>,
    },
    /// The gel's indentation per pixel (`h x w`, row-major), in metres.
    HeightMap(Vec<f64>),
}

/// Renders a press through a calibration (vtgen's or Taxim's) into a PNG, noise-free, without
/// markers.
pub fn render_press_image(calibration: &Path, pixel_size_mm: Option<f64>, shape: PressShape, out: &Path) -> Result<()> {
    let loaded = load_calibration(calibration).map_err(|e| anyhow::anyhow!(e))?;
    let pixel = match (loaded.pixel_size_mm, pixel_size_mm) {
        (_, Some(p)) if !(p > 0.0 && p < 10.0) => bail!("--pixel-size-mm {p}: allowed 0 < size < 10 mm"),
        (_, Some(p)) => p,
        (Some(p), None) => p,
        (None, None) => {
            bail!("{}: the file does not give the pixel size (Taxim's does not): give it with --pixel-size-mm", calibration.display())
        }
    };
    let config = OpticalConfig {
        calibration: Some(calibration.to_path_buf()),
        loaded_calibration: Some(std::sync::Arc::new(loaded)),
        noise_std: Some(0.0),
        ..OpticalConfig::default()
    };
    let mut sensor = config.resolve();
    sensor.sensing_area_mm = sensor.image_size.map(|n| n as f64 * pixel);
    let [w, h] = sensor.image_size;
    let image = match shape {
        PressShape::Ball { radius_mm, depth_mm, centre_px } => {
            if !(radius_mm > 0.0 && radius_mm < 100.0 && depth_mm > 0.0 && depth_mm < radius_mm) {
                bail!("--ball-radius {radius_mm}, --depth-mm {depth_mm}: 0 < depth < radius < 100 mm");
            }
            render_press(&sensor, radius_mm, depth_mm, centre_px.unwrap_or([w as f64 / 2.0, h as f64 / 2.0]))
        }
        PressShape::HeightMap(gel) => {
            if gel.len() != (w * h) as usize {
                bail!("the height map has {} values, the calibration's images {w} x {h} = {}", gel.len(), w * h);
            }
            optical_image_of_surface(&sensor, &gel)
        }
    };
    image::RgbImage::from_raw(w, h, image.rgb)
        .context("image size")?
        .save(out)
        .with_context(|| format!("cannot write {}", out.display()))?;
    println!("wrote {} ({w} x {h}, {pixel:.4} mm per pixel)", out.display());
    Ok(())
}

/// A height map from an `.npy` file (`h x w` float64/float32), in metres from `unit` (`mm` or
/// `pixels` of `pixel_size_mm`).
pub fn read_height_map(path: &Path, unit: &str, pixel_size_mm: Option<f64>) -> Result<Vec<f64>> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let (shape, values) = parse_npy(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if shape.len() != 2 {
        bail!("{}: shape {shape:?}: a height map is 2-D (rows x columns)", path.display());
    }
    let scale = match unit {
        "mm" => 1e-3,
        "pixels" => pixel_size_mm.context("--height-unit pixels needs --pixel-size-mm")? * 1e-3,
        other => bail!("--height-unit {other}: allowed mm, pixels"),
    };
    Ok(values.into_iter().map(|v| v * scale).collect())
}
