//! The checks of a parsed config or description: the one vocabulary the generator's config, the
//! randomizers, the robot description and the trainer's config check their values with.
//!
//! Each section checks its own values ([`Check`]) under the field path it is given, and names every
//! field by the field itself: `field!(self.move_seconds)` is the key `"move_seconds"` and the value,
//! so an error's path cannot drift from the field it checks (a renamed field renames its path, a
//! removed one does not compile). This holds because the YAML keys are the Rust field names: the
//! checked structs have no `serde(rename)` on their fields. [`locate`] finds a path's line and
//! column in the YAML text the values came from.

pub mod locate;
pub mod module_order;

use std::borrow::Cow;
use std::fmt::{self, Display};

/// One step of a field path: a key (a field's name, or one a section reports by name) or an
/// item's index.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Key(Cow<'static, str>),
    Index(usize),
}

impl Seg {
    pub fn key(k: impl Into<Cow<'static, str>>) -> Self {
        Seg::Key(k.into())
    }
}

/// A field path as it is written in messages: `objects[1].mesh`.
pub fn display_path(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) if s.is_empty() => s.push_str(k),
            Seg::Key(k) => {
                s.push('.');
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// A value that parsed but is not acceptable.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub path: Vec<Seg>,
    pub message: String,
}

impl Problem {
    /// The field path as messages write it.
    pub fn field(&self) -> String {
        display_path(&self.path)
    }
}

/// `field: message` (the message alone at the root).
impl Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.field() {
            field if field.is_empty() => f.write_str(&self.message),
            field => write!(f, "{field}: {}", self.message),
        }
    }
}

/// Every problem of `value`, in the order found; empty when it is acceptable.
pub fn problems(value: &impl Check) -> Vec<Problem> {
    let mut out = Vec::new();
    value.check(&mut Checks::new(&mut out));
    out
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

    /// The value here within `min` and `max` (each open or closed, or absent; NaN and infinities
    /// are not), in the words `must be 0 <= x <= 1, got 1.5`; `unit` follows the rule.
    pub fn bounded(&mut self, x: f64, min: Bound, max: Bound, unit: &str) {
        if !inside(x, min, max) {
            self.fail(format!("must be {}, got {x}", describe(min, max, "x", unit)));
        }
    }

    /// The value here a range `[lo, hi]`, `lo <= hi`, both within `min` and `max`, in the words
    /// `must be [lo, hi] with 0 <= lo <= hi, got [1.6, 0.6]`.
    pub fn bounded_range(&mut self, [lo, hi]: [f64; 2], min: Bound, max: Bound, unit: &str) {
        if !(inside(lo, min, max) && inside(hi, min, max) && lo <= hi) {
            self.fail(format!("must be [lo, hi] with {}, got [{lo}, {hi}]", describe(min, max, "lo <= hi", unit)));
        }
    }
}

/// One end of an allowed range: the value and whether it is allowed itself; None: unbounded.
pub type Bound = Option<(f64, bool)>;

/// The bound `>= v` / `<= v`.
pub const fn incl(v: f64) -> Bound {
    Some((v, true))
}

/// The bound `> v` / `< v`.
pub const fn excl(v: f64) -> Bound {
    Some((v, false))
}

fn describe(min: Bound, max: Bound, what: &str, unit: &str) -> String {
    let mut s = String::new();
    if let Some((m, allowed)) = min {
        s += &format!("{m} {} ", if allowed { "<=" } else { "<" });
    }
    s += what;
    if let Some((m, allowed)) = max {
        s += &format!(" {} {m}", if allowed { "<=" } else { "<" });
    }
    if !unit.is_empty() {
        s += &format!(" ({unit})");
    }
    s
}

fn inside(x: f64, min: Bound, max: Bound) -> bool {
    x.is_finite()
        && min.is_none_or(|(m, allowed)| if allowed { x >= m } else { x > m })
        && max.is_none_or(|(m, allowed)| if allowed { x <= m } else { x < m })
}

/// A field's key and a reference to its value: `field!(self.width)` is `("width", &self.width)`.
#[macro_export]
macro_rules! field {
    ($s:ident . $f:ident) => {
        (stringify!($f), &$s.$f)
    };
}

/// A field's key: `key!(self.far)` is `"far"`, and does not compile without the field.
#[macro_export]
macro_rules! key {
    ($s:ident . $f:ident) => {{
        let _ = &$s.$f;
        stringify!($f)
    }};
}
