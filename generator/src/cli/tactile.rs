//! `vtgen tactile calibrate DIR --ball-radius R`: an optical sensor fitted to a real unit's images
//! (`sensors::optical_fit`), written as a calibration `robot.tactile.optical.calibration` takes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::sensors::optical_fit::{CalibrationImage, CalibrationInput, fit};

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

/// Fits, writes `OUT/calibration.yaml` (+ `OUT/background.png` for the polynomial model) and prints
/// the report.
pub fn calibrate(dir: &Path, ball_radius_mm: f64, pixel_size_mm: Option<f64>, out: &Path) -> Result<()> {
    if !(ball_radius_mm > 0.0 && ball_radius_mm < 100.0) {
        bail!("--ball-radius {ball_radius_mm}: the ball's radius in mm, 0 < r < 100");
    }
    if let Some(p) = pixel_size_mm.filter(|p| !(*p > 0.0 && *p < 10.0)) {
        bail!("--pixel-size-mm {p}: allowed 0 < size < 10 mm");
    }
    let (background_path, press_paths) = calibration_images(dir)?;
    let background = read_image(&background_path, None)?;
    let dims = image::image_dimensions(&background_path)?;
    let size = [dims.0, dims.1];
    let presses = press_paths.iter().map(|p| read_image(p, Some(size))).collect::<Result<Vec<_>>>()?;
    eprintln!("vtgen: fitting {} presses ({} x {} pixels) of a {ball_radius_mm} mm ball", presses.len(), size[0], size[1]);
    let fitted = fit(&CalibrationInput { image_size: size, background: &background, presses: &presses, ball_radius_mm, pixel_size_mm })?;
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
    let header = format!(
        "# An optical sensor fitted by `vtgen tactile calibrate` to {} ({} presses of a {ball_radius_mm} mm ball).\n\
         # Use it as robot.tactile.optical.calibration: {}\n\
         # Residual over the presses' contacts (8-bit levels RMS): polynomial {:.2}, leds {:.2}; kept: {}.\n",
        dir.display(),
        presses.len(),
        yaml.display(),
        fitted.rms_polynomial,
        fitted.rms_leds,
        fitted.chosen
    );
    std::fs::write(&yaml, header + &serde_yaml::to_string(&file)?).with_context(|| format!("cannot write {}", yaml.display()))?;
    println!("pixel size: {:.4} mm{}", fitted.pixel_size_mm, if pixel_size_mm.is_some() { " (given)" } else { " (fitted)" });
    println!(
        "light model: {} (RMS over the contacts: polynomial {:.2} levels, leds {:.2} levels)",
        fitted.chosen, fitted.rms_polynomial, fitted.rms_leds
    );
    println!("{:<28} {:>9} {:>9} {:>8} {:>8} {:>11} {:>11}", "image", "centre u", "centre v", "radius", "pixels", "polynomial", "leds");
    for p in &fitted.presses {
        println!(
            "{:<28} {:>9.2} {:>9.2} {:>8.1} {:>8} {:>11.2} {:>11.2}",
            p.name, p.centre_px[0], p.centre_px[1], p.radius_px, p.pixels, p.rms_polynomial, p.rms_leds
        );
    }
    println!("(residuals: RMS in 8-bit levels over the pixels inside the contact the fit used; the images' own noise sets their floor)");
    println!("fitted in {:.2} s; wrote {}", fitted.seconds, yaml.display());
    Ok(())
}
