//! `--set KEY=VALUE` overrides, as Hydra and OmegaConf users write them: a dotted key into the
//! config (`sampling.trajectories_per_object`, `objects.0` or `objects[0]` for a list item) and a
//! YAML value (`2`, `[0, 2]`, `{train: 1, test: 1}`), set into the file's YAML tree before the
//! usual deserialization and checks.

use std::path::PathBuf;
use std::str::FromStr;

use serde_yaml::Value;

use super::ConfigError;

/// One parsed `KEY=VALUE`.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    /// As the user wrote it, for messages.
    pub text: String,
    /// The key split into its steps: map keys and list indices.
    pub keys: Vec<String>,
    pub value: Value,
}

/// A field path as serde and the checks write it (`objects[1].mesh`) or as a user writes a key
/// (`objects.1.mesh`), split into its steps.
pub fn keys(path: &str) -> Vec<String> {
    path.split(['.', '[', ']']).filter(|s| !s.is_empty()).map(str::to_string).collect()
}

impl FromStr for Override {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (key, value) = s.split_once('=').ok_or_else(|| format!("`{s}` is not KEY=VALUE (e.g. sampling.trajectories_per_object=2)"))?;
        let key = key.trim();
        if key.is_empty() || key.split('.').any(|k| k.trim().is_empty()) {
            return Err(format!("`{s}`: the key `{key}` has an empty step"));
        }
        // Brackets alone (`]`, `[]`) pass the check above but leave no step.
        let steps = keys(key);
        if steps.is_empty() {
            return Err(format!("`{s}`: the key `{key}` names no field"));
        }
        let value = serde_yaml::from_str(value).map_err(|e| format!("`{s}`: the value is not YAML: {e}"))?;
        Ok(Override { text: s.to_string(), keys: steps, value })
    }
}

impl Override {
    /// An error about this override's field (named instead of a file and line).
    pub fn error(&self, field: &str, message: String) -> ConfigError {
        ConfigError { file: PathBuf::from(format!("--set {}", self.text)), line: None, column: None, field: field.to_string(), message }
    }

    /// Sets the value into `tree`, creating missing mappings on the way.
    pub fn apply(&self, tree: &mut Value) -> Result<(), ConfigError> {
        let mut node = tree;
        for (depth, key) in self.keys.iter().enumerate() {
            let here = self.keys[..depth].join(".");
            let last = depth + 1 == self.keys.len();
            // An empty section (`robot:`) is an empty mapping.
            if node.is_null() {
                *node = Value::Mapping(Default::default());
            }
            node = match node {
                Value::Mapping(m) => {
                    let k = Value::String(key.clone());
                    if last {
                        m.insert(k, self.value.clone());
                        return Ok(());
                    }
                    m.entry(k).or_insert_with(|| Value::Mapping(Default::default()))
                }
                Value::Sequence(items) => {
                    let len = items.len();
                    let item = key
                        .parse::<usize>()
                        .ok()
                        .and_then(|i| items.get_mut(i))
                        .ok_or_else(|| self.error(&here, format!("`{key}` is not an item of this list (indices 0..{len})")))?;
                    if last {
                        *item = self.value.clone();
                        return Ok(());
                    }
                    item
                }
                _ => return Err(self.error(&here, format!("is a value, not a section: `{key}` cannot be set inside it"))),
            };
        }
        unreachable!("an override has at least one key")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(yaml: &str) -> Value {
        serde_yaml::from_str(yaml).unwrap()
    }

    #[test]
    fn sets_nested_keys_list_items_and_new_sections() {
        let mut t = tree("sampling: {trajectories_per_object: 200}\nobjects: [a, b]\n");
        for o in ["sampling.trajectories_per_object=2", "objects[1]=c", "camera.width=320", "sampling.split={train: 1, test: 1}"] {
            o.parse::<Override>().unwrap().apply(&mut t).unwrap();
        }
        assert_eq!(t, tree("sampling: {trajectories_per_object: 2, split: {train: 1, test: 1}}\nobjects: [a, c]\ncamera: {width: 320}\n"));
    }

    #[test]
    fn bad_overrides_say_what_is_wrong() {
        assert!("sampling".parse::<Override>().unwrap_err().contains("is not KEY=VALUE"));
        assert!("a..b=1".parse::<Override>().unwrap_err().contains("empty step"));
        assert!("]=1".parse::<Override>().unwrap_err().contains("names no field"));
        assert!("[].[]=1".parse::<Override>().unwrap_err().contains("names no field"));
        assert!("a=[1".parse::<Override>().unwrap_err().contains("the value is not YAML"));
        let mut t = tree("seed: 1\nobjects: [a]\n");
        let e = "seed.x=1".parse::<Override>().unwrap().apply(&mut t).unwrap_err().to_string();
        assert_eq!(e, "--set seed.x=1: seed: is a value, not a section: `x` cannot be set inside it");
        let e = "objects.3=b".parse::<Override>().unwrap().apply(&mut t).unwrap_err().to_string();
        assert!(e.contains("`3` is not an item of this list (indices 0..1)"), "{e}");
        assert_eq!(keys("objects[1].mesh"), keys("objects.1.mesh"));
    }
}
