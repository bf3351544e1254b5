//! Sampling helpers, by the rules of `datasets/python/vtdata/densefusion.py` (not its random
//! draws: the generators differ): index draws, the bilinear resize, crop cells and seed mixing.

use super::*;
use crate::model::encoder::bilinear_taps;

/// `n` indices into `0..count` (`count >= 1`) in random order: no repeats when `count >= n`,
/// else every index once and the other `n - count` drawn with replacement.
pub fn draw(rng: &mut impl Rng, count: usize, n: usize) -> Vec<usize> {
    assert!(count >= 1, "draw from an empty set");
    if count >= n {
        // Partial Fisher-Yates: the first n of a random permutation.
        let mut all: Vec<usize> = (0..count).collect();
        for i in 0..n {
            let j = rng.random_range(i..count);
            all.swap(i, j);
        }
        all.truncate(n);
        all
    } else {
        let mut v: Vec<usize> = (0..count).chain((0..n - count).map(|_| rng.random_range(0..count))).collect();
        v.shuffle(rng);
        v
    }
}

/// Resizes `h × w × 3` bytes to `size × size × 3` floats (0..255), bilinear with half-pixel
/// centres: output pixel `r` samples the input at `(r + 0.5) · h / size − 0.5`, clamped (the
/// convention of torch's `interpolate(align_corners=False)` and of the Python view; the
/// encoder's resizing uses the same taps).
pub fn resize_bilinear(src: &[u8], h: usize, w: usize, size: usize) -> Vec<f32> {
    let (ys, xs) = (bilinear_taps(h, size), bilinear_taps(w, size));
    let px = |r: usize, c: usize, k: usize| src[(r * w + c) * 3 + k] as f32;
    let mut out = vec![0.0; size * size * 3];
    for (r, &(y0, y1, wy)) in ys.iter().enumerate() {
        for (c, &(x0, x1, wx)) in xs.iter().enumerate() {
            for k in 0..3 {
                let top = px(y0, x0, k) * (1.0 - wx) + px(y0, x1, k) * wx;
                let bottom = px(y1, x0, k) * (1.0 - wx) + px(y1, x1, k) * wx;
                out[(r * size + c) * 3 + k] = top * (1.0 - wy) + bottom * wy;
            }
        }
    }
    out
}

/// The resized-crop cell holding the centre of crop pixel `i` along an axis of `n` pixels.
pub fn resized_cell(i: usize, n: usize, size: usize) -> usize {
    ((2 * i + 1) * size / (2 * n)).min(size - 1)
}

/// A small, deterministic mixing of integers into one seed (splitmix64 steps).
pub fn mix_seed(parts: &[u64]) -> u64 {
    let mut h: u64 = 0x243f_6a88_85a3_08d3;
    for &p in parts {
        h ^= p;
        h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = h;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h = z ^ (z >> 31);
    }
    h
}

/// A stable integer for a split name.
pub(crate) fn split_key(split: &str) -> u64 {
    split.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x1000_0000_01b3))
}
