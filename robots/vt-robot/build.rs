//! Finds the built-in robots: every folder `robots/<folder>/` beside this crate that holds a
//! `robot.yaml` (its `name:` is the robot's name), with the URDFs its `urdf:` and `hand_urdf:` name
//! when they are files of the checkout (relative to the folder: an arm shared by several robots,
//! a hand of its own); a `package://` URDF is read from the robot assets at load. Writes their
//! table into `$OUT_DIR/builtin_robots.rs`; no Rust code knows a robot's name.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    let robots = Path::new(&std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it")).join("..");
    println!("cargo:rerun-if-changed={}", robots.display());
    let mut found: Vec<(String, PathBuf, Option<PathBuf>, Option<PathBuf>)> = Vec::new();
    let mut folders: Vec<PathBuf> =
        std::fs::read_dir(&robots).expect("robots/ is readable").filter_map(|e| e.ok().map(|e| e.path())).collect();
    folders.sort();
    for dir in folders {
        let yaml = dir.join("robot.yaml");
        if !yaml.is_file() {
            continue;
        }
        println!("cargo:rerun-if-changed={}", yaml.display());
        let text = std::fs::read_to_string(&yaml).expect("robot.yaml is readable");
        let name = text
            .lines()
            .find_map(|l| l.strip_prefix("name:"))
            .map(|n| n.split('#').next().unwrap_or_default().trim().to_string())
            .unwrap_or_else(|| panic!("{}: no `name:` line", yaml.display()));
        // A top-level key's file, relative to the folder (None: a package:// name, or none given).
        let file = |key: &str| {
            let value = text.lines().find_map(|l| l.strip_prefix(key))?.split('#').next()?.trim().to_string();
            let path = dir.join(&value);
            (!value.starts_with("package://") && path.is_file()).then(|| {
                println!("cargo:rerun-if-changed={}", path.display());
                path.canonicalize().expect("the URDF exists")
            })
        };
        let (urdf, hand) = (file("urdf:"), file("hand_urdf:"));
        found.push((name, yaml.canonicalize().expect("the description exists"), urdf, hand));
    }
    let mut out = String::new();
    let names: Vec<String> = found.iter().map(|(n, ..)| format!("{n:?}")).collect();
    let _ = writeln!(
        out,
        "/// The built-in robots' names, by folder.\npub const BUILTIN_ROBOTS: [&str; {}] = [{}];",
        found.len(),
        names.join(", ")
    );
    let _ = writeln!(
        out,
        "/// Each built-in robot: its name, its (arm's) URDF's text and its hand's (None: not a file of the checkout) and its description's text."
    );
    let _ = writeln!(out, "const BUILTIN_TEXTS: [(&str, Option<&str>, Option<&str>, &str); {}] = [", found.len());
    let text =
        |p: &Option<PathBuf>| p.as_ref().map_or("None".to_string(), |u| format!("Some(include_str!({:?}))", u.display().to_string()));
    for (name, yaml, urdf, hand) in &found {
        let _ = writeln!(out, "    ({name:?}, {}, {}, include_str!({:?})),", text(urdf), text(hand), yaml.display().to_string());
    }
    out.push_str("];\n");
    let dest = Path::new(&std::env::var("OUT_DIR").expect("cargo sets it")).join("builtin_robots.rs");
    std::fs::write(dest, out).expect("OUT_DIR is writable");
}
