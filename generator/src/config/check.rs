//! The checks of a parsed config. Each section checks its own values ([`Check`]) under the field
//! path it is given, and names every field by the field itself: `field!(self.move_seconds)` is the
//! key `"move_seconds"` and the value, so an error's path cannot drift from the field it checks
//! (a renamed field renames its path, a removed one does not compile). The YAML keys are the Rust
//! field names: no field of the schema has a `serde(rename)`.

use std::fmt::Display;

use super::locate::Seg;

/// A value that parsed but is not acceptable.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub path: Vec<Seg>,
    pub message: String,
}

/// A config section that checks its own values.
pub trait Check {
    /// Reports every problem of `self` to `c`, whose path is the section's.
    fn check(&self, c: &mut Checks);
}

/// An optional section is checked when it is there.
impl<T: Check> Check for Option<T> {
    fn check(&self, c: &mut Checks) {
        if let Some(v) = self {
            v.check(c);
        }
    }
}

/// Where the checks are (a field path) and the problems found so far, in the order found.
pub struct Checks<'a> {
    at: Vec<Seg>,
    out: &'a mut Vec<Problem>,
}

impl<'a> Checks<'a> {
    /// Checks at the root of the config.
    pub fn new(out: &'a mut Vec<Problem>) -> Self {
        Checks { at: Vec::new(), out }
    }

    /// The checks of the value under `key` (a field name, from [`key!`] or [`field!`]).
    pub fn key(&mut self, key: &'static str) -> Checks<'_> {
        self.child(Seg::key(key))
    }

    /// The checks of item `i` of this list.
    pub fn index(&mut self, i: usize) -> Checks<'_> {
        self.child(Seg::Index(i))
    }

    /// The checks of the value at `path` below this one.
    pub fn path(&mut self, path: impl IntoIterator<Item = Seg>) -> Checks<'_> {
        let mut at = self.at.clone();
        at.extend(path);
        Checks { at, out: self.out }
    }

    fn child(&mut self, seg: Seg) -> Checks<'_> {
        self.path([seg])
    }

    /// A problem with the value here.
    pub fn fail(&mut self, message: impl Into<String>) {
        self.out.push(Problem { path: self.at.clone(), message: message.into() });
    }

    /// The value here within `lo ..= hi` (NaN is not).
    pub fn within<T: PartialOrd + Display>(&mut self, v: T, lo: T, hi: T) {
        if !(v >= lo && v <= hi) {
            self.fail(format!("{v} is out of range: allowed {lo} ..= {hi}"));
        }
    }

    /// A field within `lo ..= hi` (NaN is not).
    pub fn range<T: PartialOrd + Display + Copy>(&mut self, (key, v): (&'static str, &T), lo: T, hi: T) {
        self.key(key).within(*v, lo, hi);
    }

    /// A field within `0 < v <= hi` (NaN is not); `unit` follows `hi` in the message.
    pub fn positive(&mut self, (key, v): (&'static str, &f64), hi: f64, unit: &str) {
        if !(*v > 0.0 && *v <= hi) {
            let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
            self.key(key).fail(format!("{v} is out of range: allowed 0 < {key} <= {hi}{unit}"));
        }
    }

    /// The value here a range `(lo, hi)` with `min <= lo <= hi <= max` (NaN is not).
    pub fn ordered_pair(&mut self, (lo, hi): (f64, f64), min: f64, max: f64) {
        if !(min..=max).contains(&lo) || !(lo..=max).contains(&hi) {
            self.fail(format!("[{lo}, {hi}] is not a range: allowed {min} <= min <= max <= {max}"));
        }
    }

    /// A nested section, checked under its field's key.
    pub fn section<T: Check>(&mut self, (key, v): (&'static str, &T)) {
        v.check(&mut self.key(key));
    }
}

/// A field's key and a reference to its value: `field!(self.width)` is `("width", &self.width)`.
macro_rules! field {
    ($s:ident . $f:ident) => {
        (stringify!($f), &$s.$f)
    };
}

/// A field's key: `key!(self.far)` is `"far"`, and does not compile without the field.
macro_rules! key {
    ($s:ident . $f:ident) => {{
        let _ = &$s.$f;
        stringify!($f)
    }};
}

pub(crate) use {field, key};
