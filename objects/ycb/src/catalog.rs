use serde::{Deserialize, Serialize};

/// Geometric symmetry of an object's shape (texture ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Symmetry {
    /// No rotation maps the shape onto itself.
    #[default]
    None,
    /// A body of revolution about an axis near the model z axis (measured on the mesh,
    /// `derive_symmetries`).
    ContinuousZ,
    /// Box-like: 180-degree flips about the box's axes map the shape onto itself. The flips
    /// themselves are measured on the mesh (`derive_symmetries`): a scan's faces need not be
    /// aligned with the model axes.
    Discrete,
}

impl Symmetry {
    pub fn as_str(self) -> &'static str {
        match self {
            Symmetry::None => "none",
            Symmetry::ContinuousZ => "continuous_z",
            Symmetry::Discrete => "discrete",
        }
    }
}

impl std::str::FromStr for Symmetry {
    type Err = String;

    /// The inverse of [`Symmetry::as_str`] (e.g. `symmetry` of `models_info.json`).
    fn from_str(s: &str) -> Result<Self, String> {
        [Symmetry::None, Symmetry::ContinuousZ, Symmetry::Discrete]
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| format!("unknown symmetry '{s}' (none, continuous_z or discrete)"))
    }
}

/// The rough shape of the procedural stand-in of a catalogue object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    Box,
    RoundedBox,
    Can,
    Bottle,
    Banana,
    Mug,
    Drill,
    Scissors,
    Wrench,
}

/// One catalogue object: real dimensions and mass, and what its stand-in looks like.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CatalogEntry {
    pub id: String,
    pub name: String,
    /// Mass in kg (YCB object list).
    pub mass: f64,
    /// Axis-aligned extents of the scan in its own axes, metres.
    pub extents: [f64; 3],
    pub symmetry: Symmetry,
    pub shape: Shape,
    /// Primary and secondary colour (sRGB) of the procedural stand-in.
    pub colors: [[u8; 3]; 2],
    /// What the real surface is made of, as glTF metallic-roughness factors (matte when left out).
    #[serde(default)]
    pub surface: Surface,
}

/// glTF metallic-roughness factors of an object's surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    pub roughness: f32,
    pub metallic: f32,
}

impl Default for Surface {
    /// Matte and dielectric: cardboard, paper, and objects nothing is known about.
    fn default() -> Self {
        Surface { roughness: 0.8, metallic: 0.0 }
    }
}

/// The built-in object catalogue (`objects/ycb/catalog.yaml`, embedded at compile time).
#[derive(Debug, Clone)]
pub struct Catalog {
    entries: Vec<CatalogEntry>,
}

impl Catalog {
    pub fn builtin() -> Self {
        let entries: Vec<CatalogEntry> =
            serde_yaml::from_str(include_str!("../catalog.yaml")).expect("the embedded catalog.yaml is valid (checked by a unit test)");
        Catalog { entries }
    }

    pub fn get(&self, id: &str) -> Option<&CatalogEntry> {
        self.entries.iter().find(|e| e.id == id)
    }

    pub fn ids(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.id.as_str())
    }

    pub fn entries(&self) -> &[CatalogEntry] {
        &self.entries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_catalog_has_the_papers_eleven_objects() {
        let c = Catalog::builtin();
        let ids: Vec<&str> = c.ids().collect();
        assert_eq!(
            ids,
            [
                "003_cracker_box",
                "004_sugar_box",
                "005_tomato_soup_can",
                "006_mustard_bottle",
                "009_gelatin_box",
                "010_potted_meat_can",
                "011_banana",
                "025_mug",
                "035_power_drill",
                "037_scissors",
                "042_adjustable_wrench"
            ]
        );
        for e in c.entries() {
            assert!(e.mass > 0.0 && e.mass < 2.0, "{}", e.id);
            assert!(e.extents.iter().all(|&x| x > 0.005 && x < 0.3), "{}", e.id);
            assert_eq!(e.symmetry.as_str().parse::<Symmetry>(), Ok(e.symmetry));
        }
        assert!("box".parse::<Symmetry>().unwrap_err().contains("'box'"));
    }
}
