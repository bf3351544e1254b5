//! `robot.tactile.optical.calibration`: an optical sensor's light model measured on a real unit,
//! in place of the LED model. Two kinds of file:
//! - **vtgen's** (`calibration.yaml`, written by `vtgen tactile calibrate`): the unit's background
//!   image, its pixel size, and a polynomial in the gel's normal whose coefficients are themselves
//!   polynomials in the image position (the per-pixel-position polynomial), or the LED model's
//!   parameters when those fit the presses better;
//! - **Taxim's / TacSL's** (`polycalib.npz` with `bg.jpg` or `bg.png` beside it): a table of
//!   per-pixel-position quadratics, one per bin of the gel's slope angle and direction.
//!
//! How the image model uses them is `sensors::optical`; the file formats are in docs/tactile.md,
//! "Calibrating to your sensor".

use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::led::Led;

/// The gel-normal terms of the polynomial model, for the inner normal `m = (mx, my, mz)`: zero on
/// a flat gel (`m = -z`), so the background alone is the no-contact image.
pub const NORMAL_TERMS: [&str; 6] = ["mx", "my", "1+mz", "mx^2", "my^2", "mx*my"];
/// The image-position terms (x, y in -1..=1 over the image, as `pixel_position`): up to cubic, which
/// holds the LED model's vignetting times its LEDs' falloff exactly.
pub const POSITION_TERMS: [&str; 10] = ["1", "x", "y", "x^2", "x*y", "y^2", "x^3", "x^2*y", "x*y^2", "y^3"];

/// The values of [`NORMAL_TERMS`] at the gel's slopes `(gx, gy)` (`m = (-gx, -gy, -1) / |.|`).
pub fn normal_terms((gx, gy): (f64, f64)) -> [f64; 6] {
    let n = (1.0 + gx * gx + gy * gy).sqrt();
    let (mx, my, mz) = (-gx / n, -gy / n, -1.0 / n);
    [mx, my, 1.0 + mz, mx * mx, my * my, mx * my]
}

/// The values of [`POSITION_TERMS`] at image position `at`.
pub fn position_terms([x, y]: [f64; 2]) -> [f64; 10] {
    [1.0, x, y, x * x, x * y, y * y, x * x * x, x * x * y, x * y * y, y * y * y]
}

/// The polynomial model's light at image position `at` for the gel's slopes, per channel:
/// `sum_jk coefficients[c][j * 10 + k] * normal_j * position_k`.
pub fn polynomial_delta(coefficients: &[Vec<f64>; 3], at: [f64; 2], slopes: (f64, f64)) -> [f64; 3] {
    let (n, p) = (normal_terms(slopes), position_terms(at));
    let np = POSITION_TERMS.len();
    std::array::from_fn(|c| {
        let k = &coefficients[c];
        let mut sum = 0.0;
        for (j, nj) in n.iter().enumerate().filter(|(_, nj)| **nj != 0.0) {
            sum += nj * p.iter().zip(&k[j * np..j * np + np]).map(|(a, b)| a * b).sum::<f64>();
        }
        sum
    })
}

/// vtgen's calibration file (`calibration.yaml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// Which light model the file holds: `polynomial` or `leds`.
    pub model: String,
    /// The unit's image width and height (pixels).
    pub image_size: [u32; 2],
    /// The size of one pixel on the gel (mm), given to or identified by the fit.
    pub pixel_size_mm: f64,
    /// The gel's elastic spread (mm) the presses showed (`robot.tactile.optical.elastic_spread_mm`
    /// unless the config gives it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elastic_spread_mm: Option<f64>,
    /// `polynomial`: the no-contact image (a PNG beside this file), linear 8-bit levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background_image: Option<PathBuf>,
    /// `polynomial`: per channel (R, G, B), `NORMAL_TERMS x POSITION_TERMS` coefficients, normal
    /// term major: the image is `background + sum coefficient * normal_term * position_term`
    /// (0..=1 per level 0..=255).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coefficients: Option<[Vec<f64>; 3]>,
    /// `leds`: the LED model's parameters (as `robot.tactile.optical` takes them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lights: Option<Vec<Led>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambient: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vignetting: Option<f64>,
}

/// A loaded light model that replaces the LED model.
#[derive(Debug, Clone, PartialEq)]
pub enum LightModel {
    /// `background + sum_jk coefficients[c][j * 10 + k] * normal_j * position_k`.
    Polynomial { coefficients: [Vec<f64>; 3] },
    /// Taxim's table: `bins x bins` cells over the slope angle (`atan |grad|`, 0..=pi/2) and its
    /// direction (`atan2(gy, gx)`, -pi..=pi), each with per-channel coefficients of
    /// `[u^2, v^2, u v, u, v, 1]` in pixel coordinates (column u, row v), in 8-bit levels; channels
    /// in vtgen's order (R, G, B), i.e. the file's `grad_b`, `grad_g`, `grad_r`.
    Table { bins: usize, tables: [Vec<f64>; 3] },
}

/// A calibration loaded from its file(s).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedCalibration {
    pub image_size: [u32; 2],
    /// The pixel size (mm) the file gives (Taxim's does not: the sensor's `sensing_area_mm` over
    /// its `image_size` then).
    pub pixel_size_mm: Option<f64>,
    /// The gel's elastic spread (mm) the file gives.
    pub elastic_spread_mm: Option<f64>,
    /// The no-contact image, 0..=1 per channel, `w * h * 3` (None: the LED model's background).
    pub background: Option<Vec<f64>>,
    /// None: the file holds LED parameters, applied to the sensor when it is resolved.
    pub light: Option<LightModel>,
    /// The LED model's parameters of a `leds` file.
    pub leds: Option<CalibrationFile>,
}

impl LightModel {
    /// The light the gel adds to the background at pixel `(u, v)` (image position `at`) for the
    /// gel's slopes, per channel (0..=1 per level 0..=255).
    pub fn delta(&self, (u, v): (u32, u32), at: [f64; 2], slopes: (f64, f64)) -> [f64; 3] {
        match self {
            LightModel::Polynomial { coefficients } => polynomial_delta(coefficients, at, slopes),
            LightModel::Table { bins, tables } => {
                // Taxim shades every pixel with its cell, a flat one with the flat cell: the
                // background this model is loaded with has the flat cell in it already.
                let cell = table_cell(*bins, slopes);
                let flat = table_cell(*bins, (0.0, 0.0));
                if cell == flat {
                    return [0.0; 3];
                }
                std::array::from_fn(|c| table_value(&tables[c], *bins, cell, (u, v)) - table_value(&tables[c], *bins, flat, (u, v)))
            }
        }
    }
}

/// The cell of Taxim's table for the gel's slopes, as Taxim's simulator indexes it: the slope
/// angle's bin (`atan |grad|` over `pi/2` in `bins - 1` steps) and the direction's
/// (`atan2(gy, gx) + pi` over `2 pi` in `bins - 1` steps; a flat gel has direction 0).
fn table_cell(bins: usize, (gx, gy): (f64, f64)) -> (usize, usize) {
    let binm = (bins - 1) as f64;
    let magnitude = gx.hypot(gy);
    let angle = magnitude.atan();
    let direction = if magnitude > 0.0 { gy.atan2(gx) } else { 0.0 };
    let i = ((angle / (0.5 * std::f64::consts::PI / binm)).floor() as usize).min(bins - 1);
    let j = (((direction + std::f64::consts::PI) / (2.0 * std::f64::consts::PI / binm)).floor() as usize).min(bins - 1);
    (i, j)
}

/// One channel of a table cell's quadratic at pixel (u, v), 0..=1 per level 0..=255.
fn table_value(table: &[f64], bins: usize, (i, j): (usize, usize), (u, v): (u32, u32)) -> f64 {
    let (x, y) = (u as f64, v as f64);
    let a = [x * x, y * y, x * y, x, y, 1.0];
    let k = &table[(i * bins + j) * 6..(i * bins + j) * 6 + 6];
    a.iter().zip(k).map(|(a, b)| a * b).sum::<f64>() / 255.0
}

/// Loads a calibration: vtgen's YAML, or Taxim's `polycalib.npz` (its background `bg.png` or
/// `bg.jpg` beside it). Errors name the file and what is wrong.
pub fn load_calibration(path: &Path) -> Result<LoadedCalibration, String> {
    let is_npz = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz"));
    if is_npz { load_taxim(path) } else { load_vtgen(path) }
}

fn load_vtgen(path: &Path) -> Result<LoadedCalibration, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let file: CalibrationFile = serde_yaml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let [w, h] = file.image_size;
    if w == 0 || h == 0 || w > 2048 || h > 2048 {
        return Err(format!("{}: image_size {w} x {h}: allowed 1 ..= 2048 each", path.display()));
    }
    if !(file.pixel_size_mm > 0.0 && file.pixel_size_mm < 10.0) {
        return Err(format!("{}: pixel_size_mm {}: allowed 0 < size < 10 mm", path.display(), file.pixel_size_mm));
    }
    if let Some(spread) = file.elastic_spread_mm.filter(|s| !(*s >= 0.0 && *s < 10.0)) {
        return Err(format!("{}: elastic_spread_mm {spread}: allowed 0 <= spread < 10 mm", path.display()));
    }
    match file.model.as_str() {
        "polynomial" => {
            let coefficients =
                file.coefficients.clone().ok_or_else(|| format!("{}: model polynomial needs `coefficients`", path.display()))?;
            let terms = NORMAL_TERMS.len() * POSITION_TERMS.len();
            if let Some((c, k)) = coefficients.iter().enumerate().find(|(_, k)| k.len() != terms || k.iter().any(|v| !v.is_finite())) {
                return Err(format!("{}: coefficients[{c}]: {} finite numbers needed, got {}", path.display(), terms, k.len()));
            }
            let image =
                file.background_image.as_ref().ok_or_else(|| format!("{}: model polynomial needs `background_image`", path.display()))?;
            let image = path.parent().unwrap_or(Path::new(".")).join(image);
            let background = read_background(&image, file.image_size)?;
            Ok(LoadedCalibration {
                image_size: file.image_size,
                pixel_size_mm: Some(file.pixel_size_mm),
                elastic_spread_mm: file.elastic_spread_mm,
                background: Some(background),
                light: Some(LightModel::Polynomial { coefficients }),
                leds: None,
            })
        }
        "leds" => {
            if file.lights.is_none() || file.ambient.is_none() || file.background.is_none() || file.vignetting.is_none() {
                return Err(format!("{}: model leds needs `lights`, `ambient`, `background` and `vignetting`", path.display()));
            }
            Ok(LoadedCalibration {
                image_size: file.image_size,
                pixel_size_mm: Some(file.pixel_size_mm),
                elastic_spread_mm: file.elastic_spread_mm,
                background: None,
                light: None,
                leds: Some(file),
            })
        }
        other => Err(format!("{}: model '{other}': allowed polynomial, leds", path.display())),
    }
}

/// A background image as 0..=1 levels, `w * h * 3`; it must have the calibration's size.
fn read_background(path: &Path, [w, h]: [u32; 2]) -> Result<Vec<f64>, String> {
    let img = image::open(path).map_err(|e| format!("{}: cannot read the background image: {e}", path.display()))?.to_rgb8();
    if img.dimensions() != (w, h) {
        return Err(format!(
            "{}: the background image is {} x {}, the calibration's images {w} x {h}",
            path.display(),
            img.width(),
            img.height()
        ));
    }
    Ok(img.into_raw().into_iter().map(|b| b as f64 / 255.0).collect())
}

/// Taxim's `polycalib.npz`: `bins` and `grad_r`, `grad_g`, `grad_b`, each `bins x bins x 6`
/// float64/float32. Taxim handles its images as OpenCV does, in BGR order: its `grad_r` is fitted
/// to, and renders, the image's channel 0, which is **blue**; so `grad_r` is vtgen's blue channel
/// and `grad_b` its red. The background (`bg.png`/`bg.jpg`, read as RGB) gets the table's flat
/// cell added, as Taxim adds it to every pixel of a flat gel.
fn load_taxim(path: &Path) -> Result<LoadedCalibration, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{}: not an .npz (zip) file: {e}", path.display()))?;
    let mut array = |name: &str| -> Result<(Vec<usize>, Vec<f64>), String> {
        let entry = zip.by_name(&format!("{name}.npy")).map_err(|_| format!("{}: has no array `{name}`", path.display()))?;
        // A table of 1000 x 1000 bins is 48 MB: more is not a calibration (nor read into memory).
        const LIMIT: u64 = 64 << 20;
        if entry.size() > LIMIT {
            return Err(format!("{}: {name} is {} bytes unpacked: more than a calibration holds", path.display(), entry.size()));
        }
        let mut bytes = Vec::new();
        entry.take(LIMIT + 1).read_to_end(&mut bytes).map_err(|e| format!("{}: {name}: {e}", path.display()))?;
        if bytes.len() as u64 > LIMIT {
            return Err(format!("{}: {name} unpacks to more than a calibration holds", path.display()));
        }
        parse_npy(&bytes).map_err(|e| format!("{}: {name}: {e}", path.display()))
    };
    let (_, bins) = array("bins")?;
    let bins = *bins.first().ok_or_else(|| format!("{}: `bins` is empty", path.display()))? as usize;
    if !(2..=1000).contains(&bins) {
        return Err(format!("{}: bins {bins}: allowed 2 ..= 1000", path.display()));
    }
    let mut tables: [Vec<f64>; 3] = Default::default();
    // vtgen's R, G, B are the file's grad_b, grad_g, grad_r (BGR).
    for (c, name) in ["grad_b", "grad_g", "grad_r"].into_iter().enumerate() {
        let (shape, values) = array(name)?;
        if shape != [bins, bins, 6] {
            return Err(format!("{}: {name} has shape {shape:?}, expected [{bins}, {bins}, 6]", path.display()));
        }
        tables[c] = values;
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let (image_size, mut background) = match ["bg.png", "bg.jpg"].iter().map(|n| dir.join(n)).find(|p| p.exists()) {
        Some(bg) => {
            let img = image::open(&bg).map_err(|e| format!("{}: cannot read: {e}", bg.display()))?.to_rgb8();
            let image_size = [img.width(), img.height()];
            (image_size, read_background(&bg, image_size)?)
        }
        None if dir.join("real_bg.npy").exists() => read_npy_background(&dir.join("real_bg.npy"))?,
        None => {
            return Err(format!(
                "{}: a Taxim calibration needs its background image beside it: bg.png, bg.jpg or Taxim's real_bg.npy",
                path.display()
            ));
        }
    };
    let flat = table_cell(bins, (0.0, 0.0));
    for (k, pixel) in background.chunks_exact_mut(3).enumerate() {
        let at = ((k % image_size[0] as usize) as u32, (k / image_size[0] as usize) as u32);
        for (c, value) in pixel.iter_mut().enumerate() {
            *value += table_value(&tables[c], bins, flat, at);
        }
    }
    Ok(LoadedCalibration {
        image_size,
        pixel_size_mm: None,
        elastic_spread_mm: None,
        background: Some(background),
        light: Some(LightModel::Table { bins, tables }),
        leds: None,
    })
}

/// Taxim's `real_bg.npy`: the no-contact frame as OpenCV held it (rows x columns x 3, BGR, 0..=255
/// as uint8 or float): (image size, RGB 0..=1 levels).
fn read_npy_background(path: &Path) -> Result<([u32; 2], Vec<f64>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let (shape, values) = parse_npy(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    let [h, w, 3] = shape[..] else {
        return Err(format!("{}: shape {shape:?}: a background is rows x columns x 3 (BGR)", path.display()));
    };
    if w == 0 || h == 0 || w > 2048 || h > 2048 {
        return Err(format!("{}: {w} x {h} pixels: allowed 1 ..= 2048 each", path.display()));
    }
    let rgb = values.chunks_exact(3).flat_map(|bgr| [bgr[2], bgr[1], bgr[0]]).map(|v| (v / 255.0).clamp(0.0, 1.0)).collect();
    Ok(([w as u32, h as u32], rgb))
}

/// A `.npy` file's bytes as numpy writes them (format 1.0, C order): `descr` (e.g. `<f8`), the
/// shape as numpy prints it inside its parentheses (`"4, 4, 6"`, `""` for a scalar) and the raw
/// little-endian data. [`parse_npy`] reads it back; tests and fixtures write Taxim-style files.
pub fn npy_bytes(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({shape}), }}");
    // numpy pads the header with spaces so that the data starts on a 64-byte boundary.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

/// A `.npy` array of little-endian float64, float32, int64 or uint8 in C order: (shape, values).
pub fn parse_npy(bytes: &[u8]) -> Result<(Vec<usize>, Vec<f64>), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy array".into());
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        _ if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        _ => return Err("truncated .npy header".into()),
    };
    let header = std::str::from_utf8(bytes.get(start..start + header_len).ok_or("truncated .npy header")?).map_err(|e| e.to_string())?;
    if header.contains("'fortran_order': True") {
        return Err("Fortran-ordered arrays are not read: save it in C order".into());
    }
    let descr = header.split("'descr':").nth(1).and_then(|s| s.split('\'').nth(1)).ok_or("no descr in the .npy header")?;
    let shape_text =
        header.split("'shape':").nth(1).and_then(|s| s.split('(').nth(1)).and_then(|s| s.split(')').next()).ok_or("no shape")?;
    let shape: Vec<usize> = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| format!("bad shape {shape_text}")))
        .collect::<Result<_, _>>()?;
    let data = &bytes[start + header_len..];
    let values: Vec<f64> = match descr {
        "<f8" => data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect(),
        "<f4" => data.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")) as f64).collect(),
        "<i8" => data.chunks_exact(8).map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes")) as f64).collect(),
        "|u1" => data.iter().map(|&b| b as f64).collect(),
        other => return Err(format!("dtype {other}: float64, float32, int64 or uint8 arrays only")),
    };
    if values.len() != shape.iter().product::<usize>() {
        return Err(format!("{} values for shape {shape:?}", values.len()));
    }
    Ok((shape, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Taxim table read from an .npz (written here by hand, stored entries as `np.savez` makes
    /// them): the file's channels are BGR (`grad_r` is blue), the background gets the flat cell,
    /// and a slope adds its cell's quadratic less the flat cell's.
    #[test]
    fn a_taxim_table_is_read_in_its_bgr_order_and_evaluated() {
        let dir = tempfile::tempdir().unwrap();
        let npy = |descr: &str, shape: &str, data: Vec<u8>| npy_bytes(descr, shape, &data);
        let bins = 4usize;
        let file = std::fs::File::create(dir.path().join("polycalib.npz")).unwrap();
        let mut zip = zip::ZipWriter::new(file);
        let stored = zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Stored);
        zip.start_file("bins.npy", stored).unwrap();
        std::io::Write::write_all(&mut zip, &npy("<i8", "", 4i64.to_le_bytes().to_vec())).unwrap();
        for (k_file, name) in ["grad_r", "grad_g", "grad_b"].iter().enumerate() {
            // Cell (i, j) of the file's channel k: constant term (10 i + j) (k + 1) levels, and 1
            // level per column u.
            let scale = (k_file + 1) as f64;
            let values: Vec<f64> =
                (0..bins * bins).flat_map(|k| [0.0, 0.0, 0.0, 1.0, 0.0, (10 * (k / bins) + k % bins) as f64 * scale]).collect();
            zip.start_file(format!("{name}.npy"), stored).unwrap();
            let data = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            std::io::Write::write_all(&mut zip, &npy("<f8", "4, 4, 6", data)).unwrap();
        }
        zip.finish().unwrap();
        image::RgbImage::from_pixel(8, 6, image::Rgb([20, 40, 60])).save(dir.path().join("bg.png")).unwrap();
        let cal = load_calibration(&dir.path().join("polycalib.npz")).unwrap();
        assert_eq!((cal.image_size, cal.pixel_size_mm), ([8, 6], None));
        // The flat cell is (0, 1): direction 0 is bin floor(pi / (2 pi / 3)) = 1. At pixel (0, 0)
        // it adds 1 (k + 1) levels: 3 to red (grad_b), 2 to green, 1 to blue (grad_r).
        let background = cal.background.as_ref().unwrap();
        for (c, expected) in [23.0, 42.0, 61.0].iter().enumerate() {
            assert!((background[c] * 255.0 - expected).abs() < 1e-9, "channel {c}: {}", background[c] * 255.0);
        }
        let light = cal.light.unwrap();
        // Slope angle atan(1) = pi/4 (bin 1 of 3 per pi/2), direction 0 (bin 1): cell (1, 1), ten
        // levels (k + 1) above the flat cell; the column term cancels.
        let d = light.delta((3, 2), [0.0, 0.0], (1.0, 0.0));
        for (c, expected) in [30.0, 20.0, 10.0].iter().enumerate() {
            assert!((d[c] * 255.0 - expected).abs() < 1e-9, "channel {c}: {} vs {expected}", d[c] * 255.0);
        }
        // Direction: slopes (0, 1) point along +v, atan2 = pi/2: bin floor(1.5 pi / (2 pi / 3)) = 2.
        let d = light.delta((3, 2), [0.0, 0.0], (0.0, 1.0));
        assert!((d[2] * 255.0 - 11.0).abs() < 1e-9, "{}", d[2] * 255.0);
        // A flat gel adds nothing to the background (it has the flat cell already).
        assert_eq!(light.delta((3, 2), [0.0, 0.0], (0.0, 0.0)), [0.0; 3]);
        // A missing background is named.
        std::fs::remove_file(dir.path().join("bg.png")).unwrap();
        let e = load_calibration(&dir.path().join("polycalib.npz")).unwrap_err();
        assert!(e.contains("bg.png, bg.jpg or Taxim's real_bg.npy"), "{e}");
        // Taxim's own real_bg.npy (uint8, BGR) in its place: read as RGB.
        let bgr: Vec<u8> = (0..8 * 6).flat_map(|_| [60u8, 40, 20]).collect();
        std::fs::write(dir.path().join("real_bg.npy"), npy_bytes("|u1", "6, 8, 3", &bgr)).unwrap();
        let cal = load_calibration(&dir.path().join("polycalib.npz")).unwrap();
        assert_eq!(cal.image_size, [8, 6]);
        for (c, expected) in [23.0, 42.0, 61.0].iter().enumerate() {
            assert!((cal.background.as_ref().unwrap()[c] * 255.0 - expected).abs() < 1e-9, "channel {c}");
        }
    }

    /// The polynomial model's normal terms vanish on a flat gel (the image is the background) and
    /// its position terms are 1 at the centre.
    #[test]
    fn a_flat_gel_adds_nothing_to_the_background() {
        assert!(normal_terms((0.0, 0.0)).iter().all(|&t| t == 0.0));
        assert!(normal_terms((0.3, -0.2)).iter().all(|&t| t != 0.0));
        let model = LightModel::Polynomial { coefficients: std::array::from_fn(|c| vec![1.0 + c as f64; 60]) };
        assert_eq!(model.delta((0, 0), [0.4, -0.7], (0.0, 0.0)), [0.0; 3]);
        assert_eq!(position_terms([0.0, 0.0]), [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    }
}
