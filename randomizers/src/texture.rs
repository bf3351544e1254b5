//! Procedural textures: a serializable description ([`TextureSpec`], what the sample metadata
//! records) and its rendering to sRGB RGBA8 pixels ([`ProceduralTexture`]).
//!
//! Every procedural kind tiles seamlessly (the renderer repeats textures): noise lives on a
//! periodic lattice, stripes and linear gradients use integer wave vectors, radial gradients
//! measure distance on the torus, checkers have an even cell count, tiles wrap whole tiles.
//! Per-pixel randomness (grain, dither) comes from an integer hash of the pixel coordinates, not
//! from an RNG, so rendering is fast and allocation-free per pixel.

use std::path::Path;

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::color::{hsv, to_u8};
use crate::config::TextureKind;
use crate::images::ImageLibrary;
pub use crate::raster::ProceduralTexture;

/// A two-colour checkerboard of `squares` x `squares` cells with a faint grain, e.g. a floor.
/// Tiles seamlessly when `squares` is even.
pub fn checker_texture(size: u32, squares: u32, a: [u8; 3], b: [u8; 3]) -> ProceduralTexture {
    let squares = squares.max(1) as u64;
    ProceduralTexture::from_fn(size, |x, y| {
        let (cx, cy) = (x as u64 * squares / size as u64, y as u64 * squares / size as u64);
        let c = if (cx + cy).is_multiple_of(2) { a } else { b };
        // Deterministic grain so that flat regions are not perfectly uniform.
        let g = ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 9) as i16 - 4;
        c.map(|v| (v as i16 + g).clamp(0, 255) as u8)
    })
}

/// A complete description of a texture: rendering it at a size gives the same bytes every time.
/// Serialized with a `kind` tag (`plain`, `noise`, `stripes`, `checker`, `gradient`, `tiles`,
/// `image`); colours are sRGB bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TextureSpec {
    /// One colour with a per-pixel grain of ±`grain` levels (the canonical backdrop).
    Plain { color: [u8; 3], grain: u8 },
    /// Fractal value noise: `octaves` octaves on a periodic lattice of `cells`·2^octave cells
    /// per side, amplitudes falling by `persistence`, contrast-stretched between the two colours.
    Noise { colors: [[u8; 3]; 2], cells: u32, octaves: u32, persistence: f32, seed: u32 },
    /// Stripes: the phase (wave·pixel)/size runs through bands; band `i` has `colors[i]` and
    /// ends at phase `ends[i]` (the last end is 1). The wave vector (integers) sets angle and width.
    Stripes { colors: Vec<[u8; 3]>, ends: Vec<f32>, wave: [i32; 2] },
    /// A checkerboard of `cells`² cells (even, so it tiles).
    Checker { colors: [[u8; 3]; 2], cells: u32 },
    /// A gradient from `colors[0]` to `colors[1]`: linear and mirrored along the integer `wave`
    /// vector, or radial around `center` (texture units) on the torus.
    Gradient { colors: [[u8; 3]; 2], radial: bool, wave: [i32; 2], center: [f32; 2] },
    /// `cols` x `rows` tiles of `colors[0]` (each jittered by up to ±`jitter` levels) separated
    /// by grout lines of `colors[1]`, `grout` of a tile's width wide; odd rows shifted by half a
    /// tile when `running_bond`.
    Tiles { colors: [[u8; 3]; 2], cols: u32, rows: u32, grout: f32, jitter: u8, running_bond: bool, seed: u32 },
    /// Image `index` of group `group` of the [`ImageLibrary`] (`name` is its file name).
    Image { group: usize, index: usize, name: String },
}

impl TextureSpec {
    /// The kind this spec is of (`None` for [`TextureSpec::Plain`]).
    pub fn kind(&self) -> Option<TextureKind> {
        match self {
            TextureSpec::Plain { .. } => None,
            TextureSpec::Noise { .. } => Some(TextureKind::Noise),
            TextureSpec::Stripes { .. } => Some(TextureKind::Stripes),
            TextureSpec::Checker { .. } => Some(TextureKind::Checker),
            TextureSpec::Gradient { .. } => Some(TextureKind::Gradient),
            TextureSpec::Tiles { .. } => Some(TextureKind::Tiles),
            TextureSpec::Image { .. } => Some(TextureKind::Image),
        }
    }

    /// The pixels: a `size`² texture, or the library's image (always
    /// [`ImageLibrary::SIZE`]²). An image the library lacks renders as plain mid grey.
    pub fn render(&self, size: u32, images: &ImageLibrary) -> ProceduralTexture {
        let size = size.max(1);
        match self {
            TextureSpec::Plain { color, grain } => plain(size, *color, *grain),
            TextureSpec::Noise { colors, cells, octaves, persistence, seed } => noise(size, *colors, *cells, *octaves, *persistence, *seed),
            TextureSpec::Stripes { colors, ends, wave } => stripes(size, colors, ends, *wave),
            TextureSpec::Checker { colors, cells } => checker_texture(size, *cells, colors[0], colors[1]),
            TextureSpec::Gradient { colors, radial, wave, center } => gradient(size, *colors, *radial, *wave, *center),
            TextureSpec::Tiles { colors, cols, rows, grout, jitter, running_bond, seed } => {
                tiles(size, *colors, *cols, *rows, *grout, *jitter, *running_bond, *seed)
            }
            TextureSpec::Image { group, index, .. } => match images.image(*group, *index) {
                Some(t) => t.clone(),
                None => plain(size, [128, 128, 128], 0),
            },
        }
    }
}

/// A 32-bit integer hash of three words (lowbias32 finaliser): per-pixel randomness.
#[inline]
pub(crate) fn hash3(x: u32, y: u32, z: u32) -> u32 {
    let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77).rotate_left(13) ^ z.wrapping_mul(0xC2B2_AE3D).rotate_left(7);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^ (h >> 16)
}

/// An integer in -amp..=amp from the pixel hash.
#[inline]
fn grain(x: u32, y: u32, seed: u32, amp: i32) -> i32 {
    ((((hash3(x, y, seed) >> 16) as i32) * (2 * amp + 1)) >> 16) - amp
}

#[inline]
fn add(c: [u8; 3], d: i32) -> [u8; 3] {
    c.map(|v| (v as i32 + d).clamp(0, 255) as u8)
}

#[inline]
fn lerp3(a: [u8; 3], b: [u8; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|i| a[i] as f32 + (b[i] as f32 - a[i] as f32) * t)
}

/// A 256-entry colour ramp from `a` to `b`.
fn ramp(a: [u8; 3], b: [u8; 3]) -> Vec<[u8; 3]> {
    (0..256).map(|i| lerp3(a, b, i as f32 / 255.0).map(|v| (v + 0.5) as u8)).collect()
}

#[inline]
fn smoothstep(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// A `size`² texture with the colour `f(x, y, phase)`, where `phase` in [0, 1) is pixel (x, y)'s
/// centre projected on an integer wave vector, ((x + ½, y + ½)·wave / size) mod 1: periodic in x
/// and y. Computed incrementally along each row (no division per pixel).
fn from_phase(size: u32, wave: [i32; 2], mut f: impl FnMut(u32, u32, f32) -> [u8; 3]) -> ProceduralTexture {
    let two_n = 2 * size as i64;
    let (kx, ky) = (wave[0] as i64, wave[1] as i64);
    let step = (2 * kx).rem_euclid(two_n);
    let inv = 1.0 / two_n as f32;
    let mut m = 0i64;
    ProceduralTexture::from_fn(size, |x, y| {
        if x == 0 {
            m = (2 * ky * y as i64 + kx + ky).rem_euclid(two_n);
        } else {
            m += step;
            if m >= two_n {
                m -= two_n;
            }
        }
        f(x, y, m as f32 * inv)
    })
}

fn plain(size: u32, color: [u8; 3], amp: u8) -> ProceduralTexture {
    ProceduralTexture::from_fn(size, |x, y| add(color, grain(x, y, 0x51A1, amp as i32)))
}

fn noise(size: u32, colors: [[u8; 3]; 2], cells: u32, octaves: u32, persistence: f32, seed: u32) -> ProceduralTexture {
    let n = size as usize;
    let mut acc = vec![0f32; n * n];
    let mut amp = 1.0f32;
    for o in 0..octaves.clamp(1, 8) {
        // A periodic lattice of p x p random values, bilinearly interpolated with a smooth fade.
        let p = (cells.max(1) << o).min(size);
        let oseed = seed ^ o.wrapping_mul(0x632B_E5AB);
        let lattice: Vec<f32> = (0..p * p).map(|i| hash3(i % p, i / p, oseed) as f32 * (1.0 / 4_294_967_296.0)).collect();
        let axis: Vec<(usize, usize, f32)> = (0..size)
            .map(|x| {
                let f = (x as f32 + 0.5) * p as f32 / size as f32;
                let i = f.floor();
                let i0 = (i as u32).min(p - 1);
                (i0 as usize, ((i0 + 1) % p) as usize, smoothstep(f - i))
            })
            .collect();
        let p = p as usize;
        for (y, row) in acc.chunks_exact_mut(n).enumerate() {
            let (y0, y1, ty) = axis[y];
            let (r0, r1) = (&lattice[y0 * p..y0 * p + p], &lattice[y1 * p..y1 * p + p]);
            for (a, &(x0, x1, tx)) in row.iter_mut().zip(&axis) {
                let top = r0[x0] + (r0[x1] - r0[x0]) * tx;
                let bottom = r1[x0] + (r1[x1] - r1[x0]) * tx;
                *a += amp * (top + (bottom - top) * ty);
            }
        }
        amp *= persistence;
    }
    // Stretch to the full ramp: value noise clusters around its mean.
    let (lo, hi) = acc.iter().fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let scale = 255.0 / (hi - lo).max(1e-6);
    let ramp = ramp(colors[0], colors[1]);
    let mut rgba = vec![255u8; 4 * n * n];
    for (px, &v) in rgba.chunks_exact_mut(4).zip(&acc) {
        px[..3].copy_from_slice(&ramp[(((v - lo) * scale) as usize).min(255)]);
    }
    ProceduralTexture { width: size, height: size, rgba }
}

fn stripes(size: u32, colors: &[[u8; 3]], ends: &[f32], wave: [i32; 2]) -> ProceduralTexture {
    if colors.is_empty() || colors.len() != ends.len() {
        return plain(size, [128, 128, 128], 0);
    }
    let nc = colors.len();
    // Pixels per unit of phase, for a one-pixel anti-aliased edge between bands.
    let k = ((wave[0] as f32).powi(2) + (wave[1] as f32).powi(2)).sqrt().max(1.0);
    let px_per_phase = size as f32 / k;
    from_phase(size, wave, |x, y, ph| {
        let j = ends.iter().position(|&e| ph < e).unwrap_or(nc - 1);
        let start = if j == 0 { 0.0 } else { ends[j - 1] };
        let (d_next, d_prev) = ((ends[j] - ph) * px_per_phase, (ph - start) * px_per_phase);
        let c = if d_next < 0.5 {
            lerp3(colors[j], colors[(j + 1) % nc], 0.5 - d_next)
        } else if d_prev < 0.5 {
            lerp3(colors[j], colors[(j + nc - 1) % nc], 0.5 - d_prev)
        } else {
            colors[j].map(f32::from)
        };
        let g = grain(x, y, 0x57B1, 3) as f32;
        c.map(|v| (v + g + 0.5).clamp(0.0, 255.0) as u8)
    })
}

fn gradient(size: u32, colors: [[u8; 3]; 2], radial: bool, wave: [i32; 2], center: [f32; 2]) -> ProceduralTexture {
    let shade = |x: u32, y: u32, t: f32| {
        // Dither (±1 level) against banding.
        let g = (hash3(x, y, 0x6AD1) >> 8) as f32 * (2.0 / 16_777_216.0) - 1.0;
        lerp3(colors[0], colors[1], smoothstep(t)).map(|v| (v + g + 0.5).clamp(0.0, 255.0) as u8)
    };
    if radial {
        // Distance to the centre on the torus, per axis precomputed.
        let axis = |c: f32| -> Vec<f32> {
            (0..size)
                .map(|p| {
                    let d = ((p as f32 + 0.5) / size as f32 - c).rem_euclid(1.0);
                    let d = d.min(1.0 - d);
                    2.0 * d * d
                })
                .collect()
        };
        let (dx2, dy2) = (axis(center[0]), axis(center[1]));
        ProceduralTexture::from_fn(size, |x, y| shade(x, y, (dx2[x as usize] + dy2[y as usize]).sqrt().min(1.0)))
    } else {
        from_phase(size, wave, |x, y, ph| shade(x, y, 1.0 - (2.0 * ph - 1.0).abs()))
    }
}

#[allow(clippy::too_many_arguments)]
fn tiles(
    size: u32,
    colors: [[u8; 3]; 2],
    cols: u32,
    rows: u32,
    grout: f32,
    jitter: u8,
    running_bond: bool,
    seed: u32,
) -> ProceduralTexture {
    let (cols, rows) = (cols.max(1) as u64, rows.max(1) as u64);
    let j = jitter as i32;
    // Per-tile colour: the base colour, brightness jittered by ±jitter, each channel by ±jitter/3.
    let tile_colors: Vec<[u8; 3]> = (0..cols * rows)
        .map(|i| {
            let h = hash3((i % cols) as u32, (i / cols) as u32, seed);
            let d = |bits: u32, amp: i32| ((((h >> bits) & 0xFF) as i32 * (2 * amp + 1)) >> 8) - amp;
            let v = d(0, j);
            [0, 1, 2].map(|c| (colors[0][c] as i32 + v + d(8 + 8 * c as u32, j / 3)).clamp(0, 255) as u8)
        })
        .collect();
    let n = size as u64;
    let g_px = (grout * size as f32 / cols as f32).max(1.0);
    let shift = n / (2 * cols);
    ProceduralTexture::from_fn(size, |x, y| {
        let ty = y as u64 * rows / n;
        let local_y = (y as u64 * rows % n) as f32 / rows as f32;
        let xs = if running_bond && ty % 2 == 1 { (x as u64 + shift) % n } else { x as u64 };
        let tx = xs * cols / n;
        let local_x = (xs * cols % n) as f32 / cols as f32;
        let c = if local_x < g_px || local_y < g_px { colors[1] } else { tile_colors[(ty * cols + tx) as usize] };
        add(c, grain(x, y, 0x711E, 3))
    })
}

/// A random sRGB colour: any hue, saturation up to 0.85, value in 0.12..0.95.
fn random_color(rng: &mut impl Rng) -> (f32, f32, f32) {
    (rng.random(), rng.random_range(0.0..0.85), rng.random_range(0.12..0.95))
}

/// Luma (Rec. 601 weights on the sRGB values), 0..=1.
fn luma(c: [f32; 3]) -> f32 {
    0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]
}

/// A palette of `n` colours with visible contrast: each next colour keeps a similar hue or takes a
/// random one, and its luma differs from the previous colour's by at least 0.15 (the best of a
/// few draws).
fn palette(rng: &mut impl Rng, n: usize) -> Vec<[u8; 3]> {
    let (h, s, v) = random_color(rng);
    let mut h = h;
    let mut last = hsv(h, s, v);
    let mut out = vec![to_u8(last)];
    for _ in 1..n {
        let mut best = (f32::MIN, last, h);
        for _ in 0..6 {
            let hue = if rng.random_bool(0.5) { h + rng.random_range(-0.08..0.08) } else { rng.random() };
            let c = hsv(hue, rng.random_range(0.0..0.85), rng.random_range(0.08..0.97));
            let contrast = (luma(c) - luma(last)).abs();
            if contrast > best.0 {
                best = (contrast, c, hue);
            }
            if contrast >= 0.15 {
                break;
            }
        }
        (_, last, h) = best;
        out.push(to_u8(last));
    }
    out
}

fn pair(rng: &mut impl Rng) -> [[u8; 3]; 2] {
    let p = palette(rng, 2);
    [p[0], p[1]]
}

/// A random integer wave vector with length about `freq` (never zero), at a uniform random angle.
fn random_wave(rng: &mut impl Rng, freq: f32) -> [i32; 2] {
    let a: f32 = rng.random_range(0.0..std::f32::consts::PI);
    let w = [(freq * a.cos()).round() as i32, (freq * a.sin()).round() as i32];
    if w == [0, 0] { [1, 0] } else { w }
}

/// Draws the parameters of a texture of `kind`. For [`TextureKind::Image`], an image of the
/// library's group for `image_dir` (all images when no group has that folder); with an empty
/// library, noise instead.
pub(crate) fn random_spec(rng: &mut impl Rng, kind: TextureKind, images: &ImageLibrary, image_dir: Option<&Path>) -> TextureSpec {
    match kind {
        TextureKind::Noise => TextureSpec::Noise {
            colors: pair(rng),
            cells: rng.random_range(2..=8),
            octaves: rng.random_range(2..=4),
            persistence: rng.random_range(0.35..0.65),
            seed: rng.random(),
        },
        TextureKind::Stripes => {
            let n = rng.random_range(2..=3);
            let colors = palette(rng, n);
            // Band widths: each at least 15% of the period.
            let w: Vec<f32> = (0..n).map(|_| rng.random_range(0.15..1.0)).collect();
            let total: f32 = w.iter().sum();
            let mut acc = 0.0;
            let mut ends: Vec<f32> = w
                .iter()
                .map(|v| {
                    acc += v / total;
                    acc
                })
                .collect();
            *ends.last_mut().expect("n >= 2") = 1.0;
            let freq = rng.random_range(1.5..10.0);
            TextureSpec::Stripes { colors, ends, wave: random_wave(rng, freq) }
        }
        TextureKind::Checker => TextureSpec::Checker { colors: pair(rng), cells: 2 * rng.random_range(1..=8) },
        TextureKind::Gradient => {
            let colors = pair(rng);
            let radial = rng.random_bool(0.5);
            let freq = rng.random_range(1.0..2.5);
            let wave = random_wave(rng, freq);
            let center = [rng.random(), rng.random()];
            if radial {
                TextureSpec::Gradient { colors, radial, wave: [0, 0], center }
            } else {
                TextureSpec::Gradient { colors, radial, wave, center: [0.0, 0.0] }
            }
        }
        TextureKind::Tiles => {
            // Tile: a random colour; grout: a light or dark near-neutral.
            let tile = palette(rng, 1)[0];
            let gv: f32 = if rng.random_bool(0.5) { rng.random_range(0.75..0.95) } else { rng.random_range(0.1..0.3) };
            let grout_color = to_u8(hsv(rng.random(), rng.random_range(0.0..0.15), gv));
            let cols = rng.random_range(2..=8);
            let bricks = rng.random_bool(0.4);
            TextureSpec::Tiles {
                colors: [tile, grout_color],
                cols,
                rows: if bricks { 2 * cols } else { cols },
                grout: rng.random_range(0.02..0.08),
                jitter: rng.random_range(4..=30),
                running_bond: bricks,
                seed: rng.random(),
            }
        }
        TextureKind::Image => match images.pick(image_dir, rng) {
            Some((group, index, name)) => TextureSpec::Image { group, index, name: name.to_string() },
            None => random_spec(rng, TextureKind::Noise, images, image_dir),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn luma(t: &ProceduralTexture, x: u32, y: u32) -> f64 {
        let p = t.pixel(x, y);
        0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64
    }

    /// Sum of the per-channel variances.
    fn variance(t: &ProceduralTexture) -> f64 {
        let n = (t.width * t.height) as f64;
        (0..3)
            .map(|c| {
                let (mut s, mut s2) = (0.0, 0.0);
                for p in t.rgba.chunks_exact(4) {
                    let v = p[c] as f64;
                    s += v;
                    s2 += v * v;
                }
                s2 / n - (s / n).powi(2)
            })
            .sum()
    }

    /// (mean |Δ| across the wrap seam, mean |Δ| across each interior column boundary): columns
    /// (x, x+1) for interior, (w-1, 0) for the seam; same for rows.
    fn seams(t: &ProceduralTexture) -> ([f64; 2], [Vec<f64>; 2]) {
        let (w, h) = (t.width, t.height);
        let col = |a: u32, b: u32| (0..h).map(|y| (luma(t, a, y) - luma(t, b, y)).abs()).sum::<f64>() / h as f64;
        let row = |a: u32, b: u32| (0..w).map(|x| (luma(t, x, a) - luma(t, x, b)).abs()).sum::<f64>() / w as f64;
        ([col(w - 1, 0), row(h - 1, 0)], [(0..w - 1).map(|x| col(x, x + 1)).collect(), (0..h - 1).map(|y| row(y, y + 1)).collect()])
    }

    #[test]
    fn canonical_checker_bytes_are_unchanged() {
        // The historical checker (cell = size / squares) for a divisor size.
        let t = checker_texture(256, 8, [150, 150, 145], [110, 110, 108]);
        for (x, y) in [(0u32, 0u32), (31, 0), (32, 0), (40, 70), (255, 255)] {
            let c = if ((x / 32) + (y / 32)) % 2 == 0 { [150i16, 150, 145] } else { [110, 110, 108] };
            let g = ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 9) as i16 - 4;
            let p = t.pixel(x, y);
            assert_eq!([p[0], p[1], p[2], p[3]], [(c[0] + g) as u8, (c[1] + g) as u8, (c[2] + g) as u8, 255]);
        }
    }

    #[test]
    fn every_kind_varies_and_tiles_seamlessly() {
        let images = ImageLibrary::empty();
        for kind in TextureKind::PROCEDURAL {
            for s in 0..12u64 {
                let mut rng = ChaCha8Rng::seed_from_u64(s);
                let spec = random_spec(&mut rng, kind, &images, None);
                assert_eq!(spec.kind(), Some(kind));
                let t = spec.render(if s % 3 == 0 { 200 } else { 128 }, &images);
                assert_eq!(t.rgba.len(), 4 * (t.width * t.height) as usize);
                assert!(t.rgba.chunks_exact(4).all(|p| p[3] == 255));
                let var = variance(&t);
                assert!(var > 100.0, "{kind:?} {spec:?}: colour variance {var}");
                let (seam, interior) = seams(&t);
                for axis in 0..2 {
                    let worst = interior[axis].iter().cloned().fold(0.0, f64::max);
                    let mean = interior[axis].iter().sum::<f64>() / interior[axis].len() as f64;
                    // The wrap seam is no worse than the worst interior boundary (a checker or tile
                    // edge is a legitimate boundary), and for smooth kinds close to the typical one.
                    assert!(seam[axis] <= worst + 1.0, "{kind:?} axis {axis}: seam {} > worst interior {worst} ({spec:?})", seam[axis]);
                    if matches!(kind, TextureKind::Noise | TextureKind::Gradient) {
                        assert!(seam[axis] <= 3.0 * mean + 1.5, "{kind:?} axis {axis}: seam {} vs mean {mean}", seam[axis]);
                    }
                }
            }
        }
    }

    #[test]
    fn rendering_is_deterministic_and_seeds_matter() {
        let images = ImageLibrary::empty();
        for kind in TextureKind::PROCEDURAL {
            let spec = |s| random_spec(&mut ChaCha8Rng::seed_from_u64(s), kind, &images, None);
            assert_eq!(spec(1), spec(1));
            assert_eq!(spec(1).render(64, &images), spec(1).render(64, &images));
            assert_ne!(spec(1).render(64, &images), spec(2).render(64, &images), "{kind:?}");
        }
        // An image spec without the image renders as grey instead of panicking.
        let missing = TextureSpec::Image { group: 3, index: 9, name: "x.png".into() };
        assert_eq!(missing.render(16, &images).pixel(5, 5), [128, 128, 128, 255]);
        // With an empty library the image kind falls back to noise.
        let s = random_spec(&mut ChaCha8Rng::seed_from_u64(0), TextureKind::Image, &images, None);
        assert_eq!(s.kind(), Some(TextureKind::Noise));
    }

    #[test]
    fn spec_serializes_with_a_kind_tag() {
        let s = TextureSpec::Checker { colors: [[1, 2, 3], [4, 5, 6]], cells: 4 };
        let y = serde_yaml::to_string(&s).unwrap();
        assert!(y.contains("kind: checker"), "{y}");
        assert_eq!(serde_yaml::from_str::<TextureSpec>(&y).unwrap(), s);
    }
}
