use serde::{Deserialize, Serialize};

/// Geometric symmetry of an object's shape (texture ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Symmetry {
    /// No rotation maps the shape onto itself.
    #[default]
    None,
    /// A body of revolution about the model z axis.
    ContinuousZ,
    /// Box-like: 180-degree flips about the model axes map the shape onto itself.
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
        }
    }
}
