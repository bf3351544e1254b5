//! Mutation fuzzing on stable Rust: every loader of user input takes seeded mutations of real
//! seeds and must answer with an `Err` or a value, never a panic, a hang or an allocation sized by
//! a damaged field.
//!
//! Targets: the YAML config loader and `--set` overrides, OBJ and MTL (object meshes and the UR5e
//! arm), GLB, STL (the Allegro hand), PLY, DAE (robot meshes), URDF, robot descriptions, optical
//! calibration files (vtgen's YAML, Taxim's `.npz`), the MCAP shard reader and `vtgen validate --full`.
//! Seeds: `scenes/*.yaml`, the default robot's URDF (arm and hand as one tree), `tests/fuzz/corpus/` (OBJ, MTL,
//! ASCII STL), and binary seeds made here from the procedural meshes (GLB, binary STL, PLY) and a
//! 48x32 dataset generated at start (its shard).
//!
//! Each run replays `tests/fuzz/regressions/<target>/*` (every crash found, kept as a test) and
//! then `VTGEN_FUZZ_ITERS` mutations per target (default 300: seconds; the shard and validate
//! targets run a tenth, the URDF target 30 %); `VTGEN_FUZZ_TARGETS=glb,stl` runs some targets only. Mutations are seeded by `VTGEN_FUZZ_SEED` (default 1), so a run is
//! reproducible. A crash writes its input to `VTGEN_FUZZ_CRASH_DIR` (default the system temp
//! dir's `vtgen-fuzz-crashes/`) and fails the test; copy it into `regressions/<target>/` with the
//! fix. The long run (README, "Fuzzing"):
//!
//! ```text
//! VTGEN_FUZZ_ITERS=100000 VTGEN_FUZZ_SEED=7 cargo test --release -p vtgen --test fuzz -- --nocapture
//! ```
//!
//! Guards: a global allocator that aborts on any single allocation over 2 GiB (a size read from a
//! damaged file and trusted), naming the target and saving the input; a watchdog that does the same
//! for an input running over `VTGEN_FUZZ_TIMEOUT_S` (default 120 s: a hang, not a slow input).

use std::alloc::{GlobalAlloc, Layout, System};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Allocations above this are a trusted size field, not data.
const ALLOCATION_CAP: usize = 2 << 30;

struct CappedAllocator;

// SAFETY: forwards to the system allocator; only refuses (aborts on) oversized requests.
unsafe impl GlobalAlloc for CappedAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOCATION_CAP {
            oversized(layout.size());
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOCATION_CAP {
            oversized(layout.size());
        }
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > ALLOCATION_CAP {
            oversized(new_size);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CappedAllocator = CappedAllocator;

/// The input being tried, for the allocator guard and the watchdog to save.
struct Current {
    target: &'static str,
    started: Instant,
    input: Vec<u8>,
}

static CURRENT: Mutex<Option<Current>> = Mutex::new(None);

fn crash_dir() -> PathBuf {
    std::env::var_os("VTGEN_FUZZ_CRASH_DIR").map(PathBuf::from).unwrap_or_else(|| std::env::temp_dir().join("vtgen-fuzz-crashes"))
}

/// Saves an input that crashed `target`; returns where.
fn save_crash(target: &str, input: &[u8]) -> PathBuf {
    let dir = crash_dir().join(target);
    let _ = std::fs::create_dir_all(&dir);
    let hash = input.iter().fold(0xcbf29ce484222325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100000001b3));
    let path = dir.join(format!("crash-{hash:016x}"));
    let _ = std::fs::write(&path, input);
    path
}

fn oversized(size: usize) -> ! {
    // Small allocations below are fine: only oversized ones land here.
    if let Ok(guard) = CURRENT.try_lock()
        && let Some(c) = guard.as_ref()
    {
        let path = save_crash(c.target, &c.input);
        eprintln!("fuzz: target {} asked for {size} bytes at once (a trusted size field); input saved to {}", c.target, path.display());
        eprintln!("{}", std::backtrace::Backtrace::force_capture());
    } else {
        eprintln!("fuzz: an allocation of {size} bytes outside a fuzz input");
    }
    std::process::abort();
}

/// splitmix64: a small seeded generator, so a run is reproducible from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next() % n as u64) as usize }
    }
}

/// Integers that break size and count fields.
const INTERESTING: [u64; 10] = [0, 1, 0x7f, 0x80, 0xff, 0xffff, 0x7fff_ffff, 0xffff_ffff, 0x7fff_ffff_ffff_ffff, u64::MAX];

/// One to four mutations of `seed`: bit flips, interesting bytes and integers, deleted, duplicated
/// or truncated ranges, and tokens of the format spliced in.
fn mutate(rng: &mut Rng, seed: &[u8], tokens: &[&[u8]]) -> Vec<u8> {
    let mut d = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = d.len();
        let at = rng.below(len + 1);
        match rng.below(8) {
            0 if len > 0 => d[at.min(len - 1)] ^= 1 << rng.below(8),
            1 if len > 0 => d[at.min(len - 1)] = INTERESTING[rng.below(5)] as u8,
            2 if len >= 8 => {
                let v = INTERESTING[rng.below(INTERESTING.len())].to_le_bytes();
                let w = if rng.below(2) == 0 { 4 } else { 8 };
                let p = rng.below(len - w + 1);
                d[p..p + w].copy_from_slice(&v[..w]);
            }
            3 if len > 0 => {
                let n = 1 + rng.below((len / 4).clamp(1, 64));
                let p = rng.below(len);
                d.drain(p..(p + n).min(len));
            }
            4 if len > 0 => {
                let p = rng.below(len);
                let n = 1 + rng.below((len - p).min(256));
                let piece = d[p..p + n].to_vec();
                let q = rng.below(len + 1);
                d.splice(q..q, piece);
            }
            5 => d.truncate(at),
            6 if !tokens.is_empty() => {
                let t = tokens[rng.below(tokens.len())];
                d.splice(at..at, t.iter().copied());
            }
            _ if !tokens.is_empty() && len > 0 => {
                let t = tokens[rng.below(tokens.len())];
                let end = (at + 1 + rng.below(8)).min(len);
                d.splice(at.min(len)..end, t.iter().copied());
            }
            _ => {}
        }
    }
    d
}

const TEXT_TOKENS: &[&[u8]] = &[
    b"\n",
    b" ",
    b":",
    b"-",
    b"[",
    b"]",
    b"{",
    b"}",
    b",",
    b"\"",
    b"'",
    b"#",
    b"&a",
    b"*a",
    b"!!binary",
    b"~",
    b"null",
    b"-1",
    b"0",
    b"1e309",
    b"nan",
    b".inf",
    b"-.inf",
    b"4294967296",
    b"18446744073709551616",
    b"99999999999",
    b"<",
    b">",
    b"/>",
    b"=",
    b"\x00",
    b"\xff",
    b"f 1 2 3\n",
    b"v 1e30 -1e30 nan\n",
    b"f -1 -2 -3\n",
    b"f 0 0 0\n",
    b"vt 0 0\n",
    b"vn 0 0 0\n",
    b"usemtl x\n",
    b"mtllib ../../etc\n",
    b"map_Kd /nonexistent.png\n",
    b"newmtl\n",
    b"facet normal",
    b"vertex",
    b"endloop",
    b"<joint",
    b"<link",
    b"origin",
    b"xyz=\"",
    b"rpy=\"1e308 0 0\"",
    b"type=\"continuous\"",
    b"parent link=\"",
    b"child link=\"",
    b"element vertex 4294967295\n",
    b"element face 2147483647\n",
    b"property list uchar int vertex_indices\n",
    b"format ascii 1.0\n",
    b"end_header\n",
];

/// Runs `target` on `input`, catching a panic; returns the panic message.
fn try_input(target: &'static str, input: &[u8], run: &dyn Fn(&[u8])) -> Option<String> {
    *CURRENT.lock().unwrap() = Some(Current { target, started: Instant::now(), input: input.to_vec() });
    let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| run(input)));
    *CURRENT.lock().unwrap() = None;
    outcome
        .err()
        .map(|p| p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default())
}

/// Aborts the process, saving the input, when one input runs longer than the timeout.
fn start_watchdog() {
    let timeout = Duration::from_secs(std::env::var("VTGEN_FUZZ_TIMEOUT_S").ok().and_then(|s| s.parse().ok()).unwrap_or(120));
    std::thread::spawn(move || {
        loop {
            std::thread::sleep(Duration::from_secs(1));
            let guard = CURRENT.lock().unwrap();
            if let Some(c) = guard.as_ref()
                && c.started.elapsed() > timeout
            {
                let path = save_crash(c.target, &c.input);
                eprintln!("fuzz: target {} ran over {timeout:?} on one input (a hang); input saved to {}", c.target, path.display());
                std::process::abort();
            }
        }
    });
}

/// How a target tries one input.
type Runner = Box<dyn Fn(&[u8])>;

struct Target {
    name: &'static str,
    seeds: Vec<Vec<u8>>,
    tokens: &'static [&'static [u8]],
    /// Share of `VTGEN_FUZZ_ITERS` this target runs (slow targets run fewer).
    share: f64,
    run: Runner,
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root").to_path_buf()
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn mesh(id: &str) -> vt_objects::TexturedMesh {
    vt_objects::procedural_mesh(vt_objects::Catalog::builtin().get(id).expect("catalogue object"))
}

fn binary_stl(m: &vt_objects::TexturedMesh) -> Vec<u8> {
    let mut out = vec![0u8; 80];
    out.extend((m.indices.len() as u32 / 3).to_le_bytes());
    for t in m.indices.chunks_exact(3) {
        out.extend([0f32; 3].iter().flat_map(|v| v.to_le_bytes()));
        for &i in t {
            out.extend(m.positions[i as usize].iter().flat_map(|v| v.to_le_bytes()));
        }
        out.extend([0u8; 2]);
    }
    out
}

/// A 48x32 dataset of ten samples (8 train, 2 test), generated in process, for the shard and validate targets.
fn small_dataset(dir: &Path) -> PathBuf {
    use vtgen::config::{LoadedConfig, Override};
    let overrides: Vec<Override> = [
        "sampling.trajectories_per_object=5",
        "sampling.instances_per_trajectory=1",
        "camera.width=48",
        "camera.height=32",
        "camera.intrinsics={fx: 46, fy: 46, cx: 23.5, cy: 15.5}",
    ]
    .iter()
    .map(|o| o.parse().expect("override"))
    .collect();
    let cfg = LoadedConfig::load_with(&root().join("scenes/tiny.yaml"), &overrides).unwrap_or_else(|e| panic!("{e}"));
    let out = dir.join("dataset");
    let opts = vtgen::output::generate::GenerateOptions {
        out: out.clone(),
        shard: vtgen::plan::ShardSelector::ALL,
        resume: false,
        overwrite: false,
        jobs: 1,
        quiet: true,
        ycb_dir: None,
        mix_generators: false,
        manifest_only: false,
    };
    vtgen::output::generate::generate(&cfg, &opts).unwrap_or_else(|e| panic!("{e:#}"));
    out
}

/// A folder with a 16 x 12 background and vtgen's calibration file for it (the seed).
fn calibration_seed(work: &Path) -> (PathBuf, Vec<u8>) {
    let dir = work.join("calibration");
    std::fs::create_dir_all(&dir).unwrap();
    image::RgbImage::from_pixel(16, 12, image::Rgb([120, 130, 140])).save(dir.join("background.png")).unwrap();
    let coefficients: Vec<String> = (0..3)
        .map(|c| format!("[{}]", (0..60).map(|k| format!("{}", (k * 7 + c) % 11) as String).collect::<Vec<_>>().join(", ")))
        .collect();
    let yaml = format!(
        "model: polynomial\nimage_size: [16, 12]\npixel_size_mm: 0.1\nelastic_spread_mm: 0.3\nbackground_image: background.png\n\
         coefficients: [{}]\n",
        coefficients.join(", ")
    );
    (dir, yaml.into_bytes())
}

/// A folder with a 16 x 12 `bg.png` and a Taxim `polycalib.npz` for it (4 bins), the seed.
fn taxim_seed(work: &Path) -> (PathBuf, Vec<u8>) {
    let dir = work.join("taxim");
    std::fs::create_dir_all(&dir).unwrap();
    image::RgbImage::from_pixel(16, 12, image::Rgb([120, 130, 140])).save(dir.join("bg.png")).unwrap();
    let npy = |descr: &str, shape: &str, data: Vec<u8>| vtgen::config::optical_calibration::npy_bytes(descr, shape, &data);
    let mut bytes = std::io::Cursor::new(Vec::new());
    let mut zip = zip::ZipWriter::new(&mut bytes);
    let stored = zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Stored);
    zip.start_file("bins.npy", stored).unwrap();
    std::io::Write::write_all(&mut zip, &npy("<i8", "", 4i64.to_le_bytes().to_vec())).unwrap();
    for name in ["grad_r", "grad_g", "grad_b"] {
        zip.start_file(format!("{name}.npy"), stored).unwrap();
        let data = (0..96).flat_map(|k| ((k % 7) as f64).to_le_bytes()).collect();
        std::io::Write::write_all(&mut zip, &npy("<f8", "4, 4, 6", data)).unwrap();
    }
    zip.finish().unwrap();
    drop(zip);
    (dir, bytes.into_inner())
}

// Long on purpose: one entry per target (its seeds and how an input is tried), in one table.
/// Every built-in robot's description (`robots/<folder>/robot.yaml`), in folder order.
fn builtin_descriptions() -> Vec<Vec<u8>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("robots"))
        .unwrap()
        .filter_map(|e| Some(e.ok()?.path().join("robot.yaml")).filter(|p| p.is_file()))
        .collect();
    files.sort();
    assert!(files.len() >= 3, "the built-in robots' descriptions");
    files.iter().map(|p| read(p)).collect()
}

fn targets(work: &Path) -> Vec<Target> {
    let corpus = root().join("tests/fuzz/corpus");
    let scenes: Vec<Vec<u8>> =
        ["tiny.yaml", "tiny-hand.yaml", "paper.yaml", "demo-hand.yaml"].iter().map(|s| read(&root().join("scenes").join(s))).collect();
    let soup = mesh("005_tomato_soup_can");
    let glb = vt_dataset::encode_glb(&vt_dataset::ColoredMesh {
        positions: soup.positions.clone(),
        normals: soup.normals.clone(),
        colors: soup.vertex_colors(),
        indices: soup.indices.clone(),
    });
    let ply_seed = work.join("seed.ply");
    vt_dataset::write_ply(&ply_seed, &soup.positions, &soup.normals, &soup.indices, vt_dataset::LengthUnit::Metres).unwrap();
    let dataset = small_dataset(work);
    let shard_seed = read(&dataset.join("train/shard-00000.mcap"));
    let mesh_dir = work.join("meshes");
    std::fs::create_dir_all(&mesh_dir).unwrap();
    let mtl_seed = read(&corpus.join("obj/box.mtl"));
    let obj_seed = read(&corpus.join("obj/box.obj"));
    std::fs::write(mesh_dir.join("box.mtl"), &mtl_seed).unwrap();

    let in_file = move |name: &'static str, run: fn(&Path)| {
        let path = mesh_dir.join(name);
        move |input: &[u8]| {
            std::fs::write(&path, input).unwrap();
            run(&path);
        }
    };
    let mtl_dir = work.join("mtl");
    std::fs::create_dir_all(&mtl_dir).unwrap();
    std::fs::write(mtl_dir.join("box.obj"), &obj_seed).unwrap();
    // Outside the dataset: the validate target's dataset keeps its seed train shard.
    let shard_path = work.join("shard.mcap");
    let validate_root = dataset.clone();
    let validate_shard = dataset.join("test/shard-00000.mcap");
    let validate_seed = read(&validate_shard);
    let allegro_urdf = vt_robot::builtin_urdf(vt_robot::DEFAULT_ROBOT).expect("the default robot carries its URDFs");
    let (calibration_dir, calibration_seed) = calibration_seed(work);
    let (taxim_dir, taxim_seed) = taxim_seed(work);
    vec![
        Target {
            name: "config",
            seeds: scenes.clone(),
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(|input| {
                let _ = vtgen::config::LoadedConfig::parse(&String::from_utf8_lossy(input), Path::new("fuzz.yaml"));
            }),
        },
        Target {
            name: "set",
            seeds: [
                "sampling.trajectories_per_object=2",
                "objects[0]=011_banana",
                "camera.intrinsics={fx: 1, fy: 2, cx: 3, cy: 4}",
                "robot.tactile.resolution=16",
            ]
            .iter()
            .map(|s| s.as_bytes().to_vec())
            .collect(),
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(move |input| {
                if let Ok(o) = String::from_utf8_lossy(input).parse::<vtgen::config::Override>() {
                    let _ = vtgen::config::LoadedConfig::parse_with(&String::from_utf8_lossy(&scenes[1]), Path::new("fuzz.yaml"), &[o]);
                }
            }),
        },
        Target {
            name: "obj",
            seeds: vec![obj_seed.clone()],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(in_file("mesh.obj", |p| {
                let _ = vt_objects::load_mesh(p);
                let _ = vt_robot::mesh::read_mesh(p, glam::DVec3::ONE);
            })),
        },
        Target {
            name: "mtl",
            seeds: vec![mtl_seed],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(move |input| {
                std::fs::write(mtl_dir.join("box.mtl"), input).unwrap();
                let _ = vt_objects::load_mesh(&mtl_dir.join("box.obj"));
            }),
        },
        Target {
            name: "glb",
            seeds: vec![glb],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(in_file("mesh.glb", |p| drop(vt_objects::load_mesh(p)))),
        },
        Target {
            name: "stl",
            seeds: vec![read(&corpus.join("stl/tetra.stl")), binary_stl(&mesh("009_gelatin_box"))],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(in_file("mesh.stl", |p| drop(vt_robot::mesh::read_mesh(p, glam::DVec3::ONE)))),
        },
        Target {
            name: "ply",
            seeds: vec![read(&ply_seed)],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(in_file("mesh.ply", |p| drop(vt_dataset::read_ply(p)))),
        },
        Target {
            name: "urdf",
            seeds: vec![allegro_urdf.clone().into_bytes()],
            tokens: TEXT_TOKENS,
            share: 0.3,
            run: Box::new(|input| drop(vt_robot::RobotModel::from_urdf_str(&String::from_utf8_lossy(input), "fuzz.urdf"))),
        },
        Target {
            name: "dae",
            seeds: vec![read(&corpus.join("dae/tri.dae"))],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(in_file("mesh.dae", |p| drop(vt_robot::mesh::read_mesh(p, glam::DVec3::ONE)))),
        },
        Target {
            name: "description",
            seeds: builtin_descriptions(),
            tokens: TEXT_TOKENS,
            share: 0.3,
            run: Box::new(move |input| {
                drop(vt_robot::Robot::from_texts(&allegro_urdf, "robot.urdf", &String::from_utf8_lossy(input), "robot.yaml"))
            }),
        },
        Target {
            name: "calibration",
            seeds: vec![calibration_seed],
            tokens: TEXT_TOKENS,
            share: 1.0,
            run: Box::new(move |input| {
                std::fs::write(calibration_dir.join("calibration.yaml"), input).unwrap();
                let _ = vtgen::config::optical_calibration::load_calibration(&calibration_dir.join("calibration.yaml"));
            }),
        },
        Target {
            name: "taxim",
            seeds: vec![taxim_seed],
            tokens: &[],
            share: 1.0,
            run: Box::new(move |input| {
                std::fs::write(taxim_dir.join("polycalib.npz"), input).unwrap();
                let _ = vtgen::config::optical_calibration::load_calibration(&taxim_dir.join("polycalib.npz"));
            }),
        },
        Target {
            name: "shard",
            seeds: vec![shard_seed],
            tokens: &[],
            share: 0.1,
            run: Box::new(move |input| {
                std::fs::write(&shard_path, input).unwrap();
                if let Ok(r) = vt_dataset::ShardReader::open(&shard_path) {
                    for i in r.indices().collect::<Vec<_>>() {
                        let _ = r.read(i);
                        let _ = r.read_info(i);
                    }
                }
            }),
        },
        Target {
            name: "validate",
            seeds: vec![validate_seed],
            tokens: &[],
            share: 0.1,
            run: Box::new(move |input| {
                std::fs::write(&validate_shard, input).unwrap();
                let _ = vtgen::cli::validate::validate(&validate_root, true);
            }),
        },
    ]
}

#[test]
fn no_loader_panics_hangs_or_trusts_a_size_field() {
    let iters: usize = std::env::var("VTGEN_FUZZ_ITERS").ok().and_then(|s| s.parse().ok()).unwrap_or(300);
    let seed: u64 = std::env::var("VTGEN_FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    start_watchdog();
    let work = tempfile::Builder::new().prefix("vtgen-fuzz-").tempdir().unwrap();
    let targets = targets(work.path());
    // Panics are caught and reported once each below; the default hook would print every one.
    if std::env::var_os("VTGEN_FUZZ_VERBOSE").is_none() {
        std::panic::set_hook(Box::new(|_| {}));
    }
    let only = std::env::var("VTGEN_FUZZ_TARGETS").ok();
    let mut crashes = Vec::new();
    for t in targets.into_iter().filter(|t| only.as_deref().is_none_or(|o| o.split(',').any(|n| n == t.name))) {
        let started = Instant::now();
        let regressions = root().join("tests/fuzz/regressions").join(t.name);
        let replayed: Vec<Vec<u8>> =
            std::fs::read_dir(&regressions).map(|d| d.filter_map(|e| std::fs::read(e.ok()?.path()).ok()).collect()).unwrap_or_default();
        let mut rng = Rng(seed ^ t.name.bytes().fold(0u64, |h, b| h.wrapping_mul(31).wrapping_add(b as u64)));
        let n = ((iters as f64 * t.share).ceil() as usize).max(1);
        let inputs = t.seeds.iter().cloned().chain(replayed.iter().cloned()).chain((0..n).map(|_| {
            let s = &t.seeds[rng.below(t.seeds.len())];
            mutate(&mut rng, s, t.tokens)
        }));
        let mut tried = 0;
        for input in inputs {
            tried += 1;
            if let Some(message) = try_input(t.name, &input, &*t.run) {
                let path = save_crash(t.name, &input);
                crashes.push(format!("{}: panicked ({message}); input saved to {}", t.name, path.display()));
            }
        }
        let s = started.elapsed().as_secs_f64();
        eprintln!(
            "fuzz {:<9} {tried:>8} inputs ({} regressions) in {s:7.1} s: {:.0}/s",
            t.name,
            replayed.len(),
            tried as f64 / s.max(1e-9)
        );
    }
    let _ = std::panic::take_hook();
    assert!(crashes.is_empty(), "{} crash(es):\n{}", crashes.len(), crashes.join("\n"));
}
