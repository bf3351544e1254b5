/// An RGBA8 (sRGB) procedural texture, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct ProceduralTexture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

/// A two-colour checkerboard of `squares` x `squares` cells with a faint grain, e.g. a floor.
pub fn checker_texture(size: u32, squares: u32, a: [u8; 3], b: [u8; 3]) -> ProceduralTexture {
    let cell = (size / squares.max(1)).max(1);
    let mut rgba = Vec::with_capacity((size * size * 4) as usize);
    for y in 0..size {
        for x in 0..size {
            let c = if ((x / cell) + (y / cell)).is_multiple_of(2) { a } else { b };
            // Deterministic grain so that flat regions are not perfectly uniform.
            let g = ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 9) as i16 - 4;
            let px = c.map(|v| (v as i16 + g).clamp(0, 255) as u8);
            rgba.extend([px[0], px[1], px[2], 255]);
        }
    }
    ProceduralTexture { width: size, height: size, rgba }
}
