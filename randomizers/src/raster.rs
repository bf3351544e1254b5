//! The RGBA8 image every texture kind renders to; its own module so that the texture kinds and
//! the image library both use it without depending on each other.

/// An RGBA8 (sRGB) procedural texture, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct ProceduralTexture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl ProceduralTexture {
    /// The RGBA of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }

    /// A `size`² opaque texture with the colour `f(x, y)` at each pixel.
    pub(crate) fn from_fn(size: u32, mut f: impl FnMut(u32, u32) -> [u8; 3]) -> Self {
        let mut rgba = vec![255u8; 4 * size as usize * size as usize];
        let mut px = rgba.chunks_exact_mut(4);
        for y in 0..size {
            for x in 0..size {
                let c = f(x, y);
                px.next().expect("size² pixels")[..3].copy_from_slice(&c);
            }
        }
        ProceduralTexture { width: size, height: size, rgba }
    }
}
