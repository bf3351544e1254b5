//! User images for the `image` texture kind (e.g. a photo set), decoded and resized once.
//! The only file I/O of this crate.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::imageops::FilterType;
use rand::Rng;

use crate::config::{RandomizationConfig, TextureKind};
use crate::raster::ProceduralTexture;

/// Images decoded to [`ImageLibrary::SIZE`]² RGBA8 (sRGB), in groups, one per folder. Cheap to
/// clone (the pixels are shared).
///
/// A surface whose `image_dir` names a group's folder draws from that group; otherwise (e.g. the
/// library was loaded from a resolved path) from all images of the library.
#[derive(Debug, Clone, Default)]
pub struct ImageLibrary {
    groups: Vec<ImageGroup>,
}

#[derive(Debug, Clone)]
struct ImageGroup {
    /// The folder as the config names it (the lookup key).
    dir: PathBuf,
    /// (file name, pixels), sorted by file name.
    images: Arc<[(String, ProceduralTexture)]>,
}

impl ImageLibrary {
    /// Side of every library image in pixels.
    pub const SIZE: u32 = 256;

    /// No images: the `image` kind then falls back to noise.
    pub fn empty() -> Self {
        ImageLibrary::default()
    }

    /// All `.png`, `.jpg` and `.jpeg` files of `dir` (not recursive; extension case ignored),
    /// sorted by file name, decoded, centre-cropped to a square and resized to
    /// [`ImageLibrary::SIZE`]². Errors name the folder or the file.
    pub fn load(dir: &Path) -> Result<Self, String> {
        Ok(ImageLibrary { groups: vec![load_group(dir, dir)?] })
    }

    /// The folders of `cfg` whose surface lists the `image` kind (floor and backdrop; one group
    /// when both name the same folder), relative paths resolved against `base_dir` (e.g. the config
    /// file's folder) but keyed by the path as written, so that sampling finds them.
    pub fn for_config(cfg: &RandomizationConfig, base_dir: &Path) -> Result<Self, String> {
        let mut lib = ImageLibrary::empty();
        for t in [&cfg.floor, &cfg.backdrop] {
            if let (true, Some(dir)) = (t.kinds.contains(&TextureKind::Image), &t.image_dir)
                && !lib.groups.iter().any(|g| &g.dir == dir)
            {
                lib.groups.push(load_group(dir, &base_dir.join(dir))?);
            }
        }
        Ok(lib)
    }

    /// A library of already decoded images (any size), keyed by `dir`; sorted by name.
    pub fn from_images(dir: impl Into<PathBuf>, mut images: Vec<(String, ProceduralTexture)>) -> Self {
        images.sort_by(|a, b| a.0.cmp(&b.0));
        ImageLibrary { groups: vec![ImageGroup { dir: dir.into(), images: images.into() }] }
    }

    /// Adds the groups of `other` (a group whose folder is already present is skipped).
    pub fn extend(&mut self, other: ImageLibrary) {
        for g in other.groups {
            if !self.groups.iter().any(|h| h.dir == g.dir) {
                self.groups.push(g);
            }
        }
    }

    /// Number of images over all groups.
    pub fn len(&self) -> usize {
        self.groups.iter().map(|g| g.images.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Image `index` of group `group`.
    pub fn image(&self, group: usize, index: usize) -> Option<&ProceduralTexture> {
        self.groups.get(group)?.images.get(index).map(|(_, t)| t)
    }

    /// Number of images a surface with `image_dir` draws from (0: the `image` kind is unavailable).
    pub fn count_for(&self, image_dir: Option<&Path>) -> usize {
        match self.group_of(image_dir) {
            Some(g) => self.groups[g].images.len(),
            None => self.len(),
        }
    }

    fn group_of(&self, image_dir: Option<&Path>) -> Option<usize> {
        let dir = image_dir?;
        self.groups.iter().position(|g| g.dir == dir && !g.images.is_empty())
    }

    /// A uniformly random image for a surface with `image_dir`: (group, index, file name).
    pub(crate) fn pick(&self, image_dir: Option<&Path>, rng: &mut impl Rng) -> Option<(usize, usize, &str)> {
        let n = self.count_for(image_dir);
        if n == 0 {
            return None;
        }
        let mut k = rng.random_range(0..n);
        let (group, index) = match self.group_of(image_dir) {
            Some(g) => (g, k),
            None => {
                let mut g = 0;
                while k >= self.groups[g].images.len() {
                    k -= self.groups[g].images.len();
                    g += 1;
                }
                (g, k)
            }
        };
        Some((group, index, &self.groups[group].images[index].0))
    }
}

fn load_group(key: &Path, dir: &Path) -> Result<ImageGroup, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("cannot read image folder {}: {e}", dir.display()))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| format!("cannot read image folder {}: {e}", dir.display()))?.path();
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if path.is_file() && matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
            files.push(path);
        }
    }
    if files.is_empty() {
        return Err(format!("image folder {} has no .png, .jpg or .jpeg files", dir.display()));
    }
    files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    let mut images = Vec::with_capacity(files.len());
    for path in files {
        let img = image::open(&path).map_err(|e| format!("cannot decode image {}: {e}", path.display()))?;
        let rgba = img.resize_to_fill(ImageLibrary::SIZE, ImageLibrary::SIZE, FilterType::Triangle).to_rgba8();
        let (width, height) = rgba.dimensions();
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        images.push((name, ProceduralTexture { width, height, rgba: rgba.into_raw() }));
    }
    Ok(ImageGroup { dir: key.to_path_buf(), images: images.into() })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Writes a `w` x `h` PNG or JPEG of one colour into `dir`.
    pub(crate) fn write_image(dir: &Path, name: &str, w: u32, h: u32, c: [u8; 3]) {
        image::RgbImage::from_pixel(w, h, image::Rgb(c)).save(dir.join(name)).unwrap();
    }

    #[test]
    fn loads_sorted_resized_images_and_names_bad_folders() {
        let dir = tempfile::tempdir().unwrap();
        write_image(dir.path(), "b.png", 40, 20, [200, 10, 10]);
        write_image(dir.path(), "a.PNG", 300, 500, [10, 200, 10]);
        write_image(dir.path(), "c.jpg", 64, 64, [10, 10, 200]);
        std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
        let lib = ImageLibrary::load(dir.path()).unwrap();
        assert_eq!(lib.len(), 3);
        let names: Vec<&str> = lib.groups[0].images.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["a.PNG", "b.png", "c.jpg"]);
        for i in 0..3 {
            let t = lib.image(0, i).unwrap();
            assert_eq!((t.width, t.height, t.rgba.len()), (256, 256, 256 * 256 * 4));
        }
        assert_eq!(lib.image(0, 1).unwrap().pixel(128, 128), [200, 10, 10, 255]);
        let jpeg = lib.image(0, 2).unwrap().pixel(10, 10);
        assert!(jpeg[2] > 180 && jpeg[0] < 40, "{jpeg:?}");

        let empty = tempfile::tempdir().unwrap();
        let err = ImageLibrary::load(empty.path()).unwrap_err();
        assert!(err.contains(&empty.path().display().to_string()) && err.contains("no .png"), "{err}");
        let missing = empty.path().join("nope");
        assert!(ImageLibrary::load(&missing).unwrap_err().contains("cannot read image folder"));
        std::fs::write(empty.path().join("broken.png"), "garbage").unwrap();
        assert!(ImageLibrary::load(empty.path()).unwrap_err().contains("broken.png"));
    }

    #[test]
    fn for_config_resolves_relative_folders_and_keys_them_as_written() {
        let base = tempfile::tempdir().unwrap();
        for d in ["floor", "walls"] {
            std::fs::create_dir(base.path().join(d)).unwrap();
        }
        write_image(&base.path().join("floor"), "f.png", 8, 8, [1, 2, 3]);
        write_image(&base.path().join("walls"), "w1.png", 8, 8, [4, 5, 6]);
        write_image(&base.path().join("walls"), "w2.png", 8, 8, [7, 8, 9]);
        let mut cfg = RandomizationConfig::default();
        cfg.floor.kinds = vec![TextureKind::Image];
        cfg.floor.image_dir = Some("floor".into());
        cfg.backdrop.image_dir = Some("walls".into()); // not loaded: backdrop does not list image
        assert_eq!(ImageLibrary::for_config(&cfg, base.path()).unwrap().len(), 1);
        cfg.backdrop.kinds.push(TextureKind::Image);
        let lib = ImageLibrary::for_config(&cfg, base.path()).unwrap();
        assert_eq!(lib.len(), 3);
        assert_eq!(lib.count_for(Some(Path::new("floor"))), 1);
        assert_eq!(lib.count_for(Some(Path::new("walls"))), 2);
        assert_eq!(lib.count_for(Some(Path::new("/elsewhere"))), 3);
        cfg.floor.image_dir = Some("missing".into());
        assert!(ImageLibrary::for_config(&cfg, base.path()).unwrap_err().contains("missing"));
    }
}
