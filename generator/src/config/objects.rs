//! `objects:` catalogue ids, or custom objects with their own meshes.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

/// A catalogue id, or a custom object with its own mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ObjectSpec {
    Catalog(String),
    Custom(CustomObject),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomObject {
    pub id: String,
    /// OBJ (+MTL), glTF or GLB, relative to the config file.
    pub mesh: PathBuf,
    #[serde(default = "default_mass")]
    pub mass: f64,
    #[serde(default)]
    pub symmetry: vt_objects::Symmetry,
}

fn default_mass() -> f64 {
    0.2
}

impl Check for CustomObject {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.mass), 100.0, "kg");
        if self.id.is_empty() || !self.id.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-') {
            c.key(key!(self.id)).fail(format!("'{}' is not a valid id: use letters, digits, '_' and '-'", self.id));
        }
    }
}

impl ObjectSpec {
    pub fn id(&self) -> &str {
        match self {
            ObjectSpec::Catalog(id) => id,
            ObjectSpec::Custom(c) => &c.id,
        }
    }
}

impl<'de> Deserialize<'de> for ObjectSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = ObjectSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a catalogue object id (e.g. 003_cracker_box) or a custom object {id, mesh, mass, symmetry}")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ObjectSpec, E> {
                Ok(ObjectSpec::Catalog(v.to_string()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<ObjectSpec, A::Error> {
                CustomObject::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(ObjectSpec::Custom)
            }
        }
        d.deserialize_any(V)
    }
}
