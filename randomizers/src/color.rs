//! Colour helpers: blackbody colour, HSV, sRGB encoding.

/// Linear-RGB colour of a blackbody at `kelvin` (1667..=25000 K; clamped), largest component 1.
///
/// The chromaticity follows Kim et al.'s cubic fit of the Planckian locus (CIE 1931 xy), turned
/// into linear sRGB (D65) primaries; components that fall outside the gamut are clipped at 0.
pub fn blackbody_rgb(kelvin: f64) -> [f32; 3] {
    let t = kelvin.clamp(1667.0, 25000.0);
    let (t2, t3) = (t * t, t * t * t);
    let x = if t <= 4000.0 {
        -0.2661239e9 / t3 - 0.2343589e6 / t2 + 0.8776956e3 / t + 0.179910
    } else {
        -3.0258469e9 / t3 + 2.1070379e6 / t2 + 0.2226347e3 / t + 0.240390
    };
    let (x2, x3) = (x * x, x * x * x);
    let y = if t <= 2222.0 {
        -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * x - 0.20219683
    } else if t <= 4000.0 {
        -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * x - 0.16748867
    } else {
        3.0817580 * x3 - 5.87338670 * x2 + 3.75112997 * x - 0.37001483
    };
    let (cx, cy, cz) = (x / y, 1.0, (1.0 - x - y) / y);
    let r = 3.2404542 * cx - 1.5371385 * cy - 0.4985314 * cz;
    let g = -0.9692660 * cx + 1.8760108 * cy + 0.0415560 * cz;
    let b = 0.0556434 * cx - 0.2040259 * cy + 1.0572252 * cz;
    normalize_max([r as f32, g as f32, b as f32])
}

/// HSV (all in 0..=1, hue wrapping) to RGB in 0..=1.
pub fn hsv(h: f32, s: f32, v: f32) -> [f32; 3] {
    let h6 = h.rem_euclid(1.0) * 6.0;
    let sector = (h6.floor() as i32).min(5);
    let f = h6 - sector as f32;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match sector {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// Negative components clipped to 0, then scaled so that the largest is 1 (black stays black).
pub fn normalize_max(c: [f32; 3]) -> [f32; 3] {
    let c = c.map(|v| v.max(0.0));
    let m = c[0].max(c[1]).max(c[2]);
    if m > 0.0 { c.map(|v| v / m) } else { c }
}

/// A 0..=1 colour as 8-bit (the values are taken as already sRGB-encoded).
pub fn to_u8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blackbody_is_warm_to_cool_and_white_near_6500k() {
        let warm = blackbody_rgb(2700.0);
        let d65 = blackbody_rgb(6504.0);
        let cool = blackbody_rgb(9000.0);
        assert_eq!(warm[0], 1.0);
        assert!(warm[1] < 0.75 && warm[2] < 0.5, "{warm:?}");
        assert!(d65.iter().all(|&v| v > 0.9), "{d65:?}");
        assert_eq!(cool[2], 1.0);
        assert!(cool[0] < 0.9, "{cool:?}");
        // Monotone: blue/red grows with temperature.
        let ratio = |k: f64| {
            let c = blackbody_rgb(k);
            c[2] / c[0]
        };
        let mut last = 0.0;
        for k in (1700..25000).step_by(100) {
            let r = ratio(k as f64);
            assert!(r >= last, "{k}");
            last = r;
        }
    }

    #[test]
    fn hsv_primaries() {
        assert_eq!(hsv(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        assert_eq!(hsv(1.0 / 3.0, 1.0, 1.0).map(|v| (v * 1e4).round()), [0.0, 1e4, 0.0]);
        assert_eq!(hsv(0.5, 0.0, 0.5), [0.5, 0.5, 0.5]);
        assert_eq!(to_u8([1.0, 0.5, 0.0]), [255, 128, 0]);
    }
}
