//! The generator's build identity (`VTGEN_BUILD_ID`): a hash of everything that decides a
//! dataset's bytes (the workspace crates' sources and shaders, and Cargo.lock's dependency
//! versions). A dataset records it (`generator.json`) so that `--resume` never mixes shards made
//! by two different generators unknowingly.

use std::path::{Path, PathBuf};

/// 64-bit FNV-1a: small, stable across Rust versions (unlike `DefaultHasher`).
fn fnv1a(hash: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *hash ^= *b as u64;
        *hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().and_then(|x| x.to_str()).is_some_and(|x| ["rs", "wgsl", "toml"].contains(&x)) {
            out.push(p);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let root = manifest.parent().expect("the generator sits in the workspace").to_path_buf();
    // The crates a dataset's bytes come from (the trainer's are not among them).
    let dirs =
        ["generator/src", "generator/presets", "check/src", "objects/ycb/src", "randomizers/src", "datasets/src", "robots/vt-robot/src"];
    let mut files = Vec::new();
    for d in dirs {
        let dir = root.join(d);
        println!("cargo:rerun-if-changed={}", dir.display());
        collect(&dir, &mut files);
    }
    for f in ["Cargo.lock", "generator/Cargo.toml"] {
        println!("cargo:rerun-if-changed={}", root.join(f).display());
        files.push(root.join(f));
    }
    files.sort();
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for f in &files {
        fnv1a(&mut hash, f.strip_prefix(&root).unwrap_or(f).to_string_lossy().as_bytes());
        // Line endings normalised, so a checkout on another OS builds the same identity.
        let text = std::fs::read(f).unwrap_or_default();
        let text: Vec<u8> = text.into_iter().filter(|&b| b != b'\r').collect();
        fnv1a(&mut hash, &text);
    }
    println!("cargo:rustc-env=VTGEN_BUILD_ID={hash:016x}");
}
