//! The YAML config. Parsing rejects unknown keys; every error names the file, line, column and
//! field path, and out-of-range values name the allowed range.

mod locate;
mod schema;

use std::path::{Path, PathBuf};

pub use schema::*;

/// A config error, formatted `FILE:LINE:COL: FIELD: message`.
#[derive(Debug, thiserror::Error)]
#[error("{}{}{}", location(.file, .line, .column), field_prefix(.field), .message)]
pub struct ConfigError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub column: Option<usize>,
    pub field: String,
    pub message: String,
}

fn location(file: &Path, line: &Option<usize>, column: &Option<usize>) -> String {
    match (line, column) {
        (Some(l), Some(c)) => format!("{}:{l}:{c}: ", file.display()),
        (Some(l), None) => format!("{}:{l}: ", file.display()),
        _ => format!("{}: ", file.display()),
    }
}

fn field_prefix(field: &str) -> String {
    if field.is_empty() || field == "." { String::new() } else { format!("{field}: ") }
}

/// A parsed and validated config, with the file it came from.
#[derive(Debug, Clone)]
pub struct LoadedConfig {
    pub config: Config,
    pub path: PathBuf,
    /// Directory that relative paths in the config are resolved against.
    pub base_dir: PathBuf,
}

impl LoadedConfig {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: path.to_path_buf(),
            line: None,
            column: None,
            field: String::new(),
            message: format!("cannot read config: {e}"),
        })?;
        Self::parse(&text, path)
    }

    /// Parses config text; `path` is used for messages and to resolve relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let de = serde_yaml::Deserializer::from_str(text);
        let config: Config = serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            let loc = inner.location();
            let mut message = inner.to_string();
            // serde_yaml appends " at line L column C"; the location is printed up front instead.
            if let Some(pos) = message.find(" at line ") {
                message.truncate(pos);
            }
            ConfigError {
                file: path.to_path_buf(),
                line: loc.as_ref().map(|l| l.line()),
                column: loc.as_ref().map(|l| l.column()),
                field,
                message,
            }
        })?;
        let problems = config.validate();
        if let Some(p) = problems.into_iter().next() {
            let (line, column) = locate::locate(text, &p.path).map_or((None, None), |(l, c)| (Some(l), Some(c)));
            return Err(ConfigError { file: path.to_path_buf(), line, column, field: locate::display_path(&p.path), message: p.message });
        }
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(LoadedConfig { config, path: path.to_path_buf(), base_dir })
    }

    /// Resolves a path written in the config relative to the config file's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() { p.to_path_buf() } else { self.base_dir.join(p) }
    }
}

#[cfg(test)]
mod tests;
