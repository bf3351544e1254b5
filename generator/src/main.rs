use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};
use vtgen::config::LoadedConfig;
use vtgen::output::generate::{GenerateOptions, generate};
use vtgen::plan::{Plan, SPLITS, ShardSelector};

/// Synthetic visuotactile training data for in-hand 6D object pose estimation.
#[derive(Parser)]
#[command(name = "vtgen", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate a dataset (or this job's shards of it) from a YAML config.
    Generate {
        /// The YAML config, e.g. scenes/tiny.yaml.
        config: PathBuf,
        /// Output directory (default: the config's output.dir).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Generate only shards j with j mod N = i (distributed runs), e.g. 0/4.
        #[arg(long, value_name = "i/N")]
        shard: Option<ShardSelector>,
        /// Continue an interrupted run: keep complete shards, redo the rest.
        #[arg(long)]
        resume: bool,
        /// Replace a dataset that is already in the output directory.
        #[arg(long, conflicts_with = "resume")]
        overwrite: bool,
        /// Parallel shard workers, each with its own renderer.
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        /// YCB download to take real meshes from (overrides the config's ycb_dir).
        #[arg(long)]
        ycb_dir: Option<PathBuf>,
        /// No progress bar; errors only.
        #[arg(long)]
        quiet: bool,
    },
    /// Print what a config would generate (objects, splits, shards, disk size) and write nothing.
    Plan { config: PathBuf },
    /// Measure samples/s and the time per stage on the config's first samples (writes nothing).
    Bench {
        config: PathBuf,
        #[arg(long, default_value_t = 40)]
        samples: u64,
        /// Parallel workers, as `generate --jobs`.
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        #[arg(long)]
        ycb_dir: Option<PathBuf>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Run the grasp loop alone (no rendering) over the first trajectories of every object and
    /// report, per object, how many kept the object through all instances, the attempts and
    /// failures, and the worst recorded instance (penetration, contacts, slip, floor clearance).
    Grasps {
        config: PathBuf,
        /// Trajectories per object.
        #[arg(long, default_value_t = 20)]
        trajectories: u32,
        /// Instances per trajectory (default: the config's).
        #[arg(long)]
        instances: Option<u32>,
        /// Parallel workers (default: the machine's cores).
        #[arg(long)]
        jobs: Option<usize>,
        #[arg(long)]
        ycb_dir: Option<PathBuf>,
        /// Fail (exit status 1) when an object keeps fewer than this fraction of its trajectories.
        #[arg(long)]
        min_kept: Option<f64>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// A contact sheet (PNG) of a config's samples (generated in memory) or of a dataset's: RGB with
    /// mask, tactile points and pose axes, next to the depth.
    Preview {
        /// A YAML config or a dataset directory.
        source: PathBuf,
        #[arg(long, default_value_t = 6)]
        n: usize,
        #[arg(long, default_value = "preview.png")]
        out: PathBuf,
        /// Width of each row in pixels.
        #[arg(long, default_value_t = 960)]
        width: u32,
        /// Rows side by side.
        #[arg(long, default_value_t = 1)]
        columns: u32,
        #[arg(long)]
        ycb_dir: Option<PathBuf>,
    },
    /// Summarise a dataset: samples per split and object, shards, bytes, occlusion, touch, grasps.
    Inspect {
        dataset: PathBuf,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Check a dataset: checksums, shard indexes, every sample's messages, and the ground truth
    /// (re-projected onto mask and depth) of one sample per shard, or of all with --full.
    Validate {
        dataset: PathBuf,
        #[arg(long)]
        full: bool,
    },
    /// Plots (SVG) of what a dataset covers — positions, rotations, occlusion, touch — and a
    /// Markdown page tying them together.
    Stats {
        dataset: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// Convert a dataset for other tools.
    Export {
        #[command(subcommand)]
        format: ExportFormat,
    },
    /// Write one sample as .npy files (rgb, depth, mask, K, T_camera_object) and info.json.
    Dump {
        dataset: PathBuf,
        #[arg(long, default_value = "train")]
        split: String,
        #[arg(long, default_value_t = 0)]
        index: u64,
        #[arg(long)]
        out: PathBuf,
        /// Also write the float depth as OpenEXR (depth.exr, channel Z, metres).
        #[arg(long)]
        exr: bool,
    },
}

#[derive(Subcommand)]
enum ExportFormat {
    /// The BOP format (scene_gt.json, scene_camera.json, scene_gt_info.json, rgb/, depth/, mask/,
    /// mask_visib/, models/ in mm), read unchanged by the BOP toolkit; tactile points beside it.
    Bop {
        dataset: PathBuf,
        /// A new (or empty) directory.
        out: PathBuf,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Also write the exact float depth as OpenEXR (`depth_exr/IIIIII.exr`, channel Z, metres).
        #[arg(long)]
        exr: bool,
    },
}

fn human_bytes(b: f64) -> String {
    let units = ["B", "KB", "MB", "GB", "TB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1000.0 && u < units.len() - 1 {
        v /= 1000.0;
        u += 1;
    }
    format!("{v:.1} {}", units[u])
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Generate { config, out, shard, resume, overwrite, jobs, ycb_dir, quiet } => {
            let cfg = LoadedConfig::load(&config)?;
            let out = out.unwrap_or_else(|| cfg.config.output.dir.clone());
            let opts =
                GenerateOptions { out: out.clone(), shard: shard.unwrap_or(ShardSelector::ALL), resume, overwrite, jobs, quiet, ycb_dir };
            let s = generate(&cfg, &opts)?;
            if !quiet {
                eprintln!("renderer: {}", s.adapter);
                eprintln!(
                    "generated {} samples in {} shard(s) ({} skipped as complete), {} in {:.1} s: {:.1} samples/s",
                    s.samples,
                    s.shards_written,
                    s.shards_skipped,
                    human_bytes(s.bytes as f64),
                    s.seconds,
                    s.samples as f64 / s.seconds.max(1e-9)
                );
                eprintln!("dataset {}: {}", out.display(), if s.complete { "complete" } else { "incomplete (other shards pending)" });
            }
            Ok(())
        }
        Command::Plan { config } => {
            let cfg = LoadedConfig::load(&config)?;
            let c = &cfg.config;
            let plan = Plan::new(c);
            let s = &c.sampling;
            println!("config      {}", config.display());
            println!("objects     {} ({})", c.objects.len(), c.objects.iter().map(|o| o.id()).collect::<Vec<_>>().join(", "));
            println!(
                "samples     {} objects x {} trajectories x {} instances = {}",
                c.objects.len(),
                s.trajectories_per_object,
                s.instances_per_trajectory,
                plan.total_samples()
            );
            for (i, split) in SPLITS.iter().enumerate() {
                let shards = plan.shards.iter().filter(|x| x.split == *split).count();
                println!("{split:<11} {} samples in {shards} shard(s) of up to {}", plan.samples_per_split[i], plan.samples_per_shard);
            }
            let (w, h) = (c.camera.width as f64, c.camera.height as f64);
            let raw = w * h * (3.0 + 4.0 + 1.0) + 2048.0;
            // Measured: zstd keeps ~12% of the raw bytes of canonical scenes; randomized textures compress worse.
            let est = raw * plan.total_samples() as f64;
            println!(
                "disk        {} raw; about {} to {} with zstd (estimate)",
                human_bytes(est),
                human_bytes(est * 0.1),
                human_bytes(est * 0.4)
            );
            println!("output      {}", c.output.dir.display());
            if let Some(g) = c.robot.as_ref().map(|r| &r.grasp) {
                // Occlusion depends on the hand's pose in the picture: measured, not planned.
                println!(
                    "occlusion   back of the hand to the camera in {:.0}% of arm moves; `vtgen bench {}` measures the share per occlusion bin",
                    100.0 * g.back_to_camera_share,
                    config.display()
                );
            }
            Ok(())
        }
        Command::Bench { config, samples, jobs, ycb_dir, json } => {
            let cfg = LoadedConfig::load(&config)?;
            let r = vtgen::cli::bench::bench(&cfg, samples, jobs, ycb_dir.as_ref())?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                println!("adapter            {}", r.adapter);
                println!(
                    "samples            {} in {:.2} s with {} job(s): {:.1} samples/s",
                    r.samples, r.seconds, r.jobs, r.samples_per_second
                );
                let per = |x: f64| 1e3 * x / r.samples as f64;
                println!("per sample (summed over jobs):");
                println!("  physics          {:7.2} ms", per(r.physics));
                println!(
                    "  main render      {:7.2} ms  (readback {:.2} ms of it and the tactile views)",
                    per(r.main_render),
                    per(r.readback)
                );
                println!(
                    "  tactile render   {:7.2} ms  ({:.0}% of the main render)",
                    per(r.tactile_render),
                    100.0 * r.tactile_over_main_render
                );
                println!("  tactile points   {:7.2} ms", per(r.tactile_extraction));
                println!("  occlusion        {:7.2} ms", per(r.occlusion));
                println!("  encode + write   {:7.2} ms  (writer thread, overlapped)", per(r.encode_and_write));
                println!("peak RSS           {:.0} MiB", r.peak_rss_mib);
                let bins = vtgen::annotate::occlusion::BINS;
                println!("occlusion          {:>8} {:>8} {:>8}  (share of samples per bin)", bins[0], bins[1], bins[2]);
                let mut all = [0u64; 3];
                for (id, b) in &r.occlusion_bins {
                    let n = b.iter().sum::<u64>().max(1) as f64;
                    println!(
                        "  {id:<24}{:>7.1}% {:>7.1}% {:>7.1}%",
                        100.0 * b[0] as f64 / n,
                        100.0 * b[1] as f64 / n,
                        100.0 * b[2] as f64 / n
                    );
                    all.iter_mut().zip(b).for_each(|(a, x)| *a += x);
                }
                let n = all.iter().sum::<u64>().max(1) as f64;
                println!(
                    "  {:<24}{:>7.1}% {:>7.1}% {:>7.1}%",
                    "all",
                    100.0 * all[0] as f64 / n,
                    100.0 * all[1] as f64 / n,
                    100.0 * all[2] as f64 / n
                );
                for s in &r.skipped_trajectories {
                    println!("skipped            {s}");
                }
            }
            Ok(())
        }
        Command::Grasps { config, trajectories, instances, jobs, ycb_dir, min_kept, json, quiet } => {
            let cfg = LoadedConfig::load(&config)?;
            let objects = vtgen::assets::load_objects(&cfg, ycb_dir.as_ref())?;
            let jobs = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let opts = vtgen::cli::grasps::GraspCheckOptions { trajectories, instances, jobs, quiet };
            let r = vtgen::cli::grasps::check_grasps(&cfg, &objects, &opts)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                print!("{}", r.markdown());
            }
            if let Some(min) = min_kept
                && r.worst_kept_fraction() < min
            {
                anyhow::bail!("an object kept {:.1}% of its trajectories, below --min-kept {min}", 100.0 * r.worst_kept_fraction());
            }
            Ok(())
        }
        Command::Preview { source, n, out, width, columns, ycb_dir } => {
            let samples = vtgen::cli::preview::samples(&source, n, ycb_dir.as_ref())?;
            vtgen::cli::preview::write_sheet(&samples, &out, width, columns)?;
            println!("wrote {} ({} samples)", out.display(), samples.len());
            Ok(())
        }
        Command::Inspect { dataset, json } => {
            let r = vtgen::cli::inspect::inspect(&dataset)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
                return Ok(());
            }
            println!(
                "dataset     {} ({}; {}/{} shards, {})",
                dataset.display(),
                if r.complete { "complete" } else { "incomplete" },
                r.shards_complete,
                r.shards,
                human_bytes(r.bytes as f64)
            );
            for (split, objects) in &r.samples {
                let total: u64 = objects.values().sum();
                let per: Vec<String> = objects.iter().map(|(o, c)| format!("{o} {c}")).collect();
                println!("{split:<11} {total} samples: {}", per.join(", "));
            }
            for (split, bins) in &r.occlusion {
                let total = bins.values().sum::<u64>().max(1) as f64;
                let occ: Vec<String> = bins.iter().map(|(b, c)| format!("{b} {c} ({:.1}%)", 100.0 * *c as f64 / total)).collect();
                println!("occlusion   {split}: {}", occ.join(", "));
            }
            println!("randomized  {:.1}%", 100.0 * r.randomized_share);
            if let Some([lo, med, hi]) = r.tactile_points {
                println!("touch       tactile points per sample: min {lo}, median {med}, max {hi}");
                let c: Vec<String> = r.contact_share.iter().map(|(p, s)| format!("{p} {:.0}%", 100.0 * s)).collect();
                println!("contacts    {}", c.join(", "));
            }
            if let Some(g) = &r.grasp {
                println!("grasps      {g}");
            }
            Ok(())
        }
        Command::Validate { dataset, full } => {
            let r = vtgen::cli::validate::validate(&dataset, full)?;
            for p in &r.problems {
                eprintln!("problem: {p}");
            }
            println!(
                "{}: {} shards, {} samples read, ground truth checked on {}: {}",
                dataset.display(),
                r.shards,
                r.samples,
                r.ground_truth_checked,
                if r.problems.is_empty() { "valid".to_string() } else { format!("{} problem(s)", r.problems.len()) }
            );
            anyhow::ensure!(r.problems.is_empty(), "{} is not valid ({} problem(s))", dataset.display(), r.problems.len());
            Ok(())
        }
        Command::Stats { dataset, out } => {
            let files = vtgen::cli::stats::write_stats(&dataset, &out)?;
            println!("wrote {} files to {}: {}", files.len(), out.display(), files.join(", "));
            Ok(())
        }
        Command::Export { format: ExportFormat::Bop { dataset, out, quiet, exr } } => {
            // The renderer the dataset was made with (its adapter choice), for the amodal masks.
            let renderer = std::fs::read(dataset.join("config.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
                .and_then(|c| serde_json::from_value(c["renderer"].clone()).ok())
                .unwrap_or_default();
            let r = vtgen::cli::export::export_bop(&dataset, &out, &renderer, quiet, exr)?;
            println!("wrote {}: {} objects, {} scenes, {} images (BOP format)", out.display(), r.objects, r.scenes, r.images);
            Ok(())
        }
        Command::Dump { dataset, split, index, out, exr } => vtgen::cli::dump::dump(&dataset, &split, index, &out, exr),
    }
}

/// Mesa's drivers print "XDG_RUNTIME_DIR is invalid or not set" on headless machines; give them a
/// private runtime directory when there is none.
fn quiet_headless_mesa() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let dir = std::env::temp_dir().join("vtgen-xdg-runtime");
    if std::fs::create_dir_all(&dir).is_ok() {
        use std::os::unix::fs::PermissionsExt;
        let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        // SAFETY: called first thing in main, before any other thread exists.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}

/// With several workers, each worker's lavapipe device spawning its own rasterizer threads (one
/// per core by default) oversubscribes the cores and slows the physics that shares them: measured
/// on 2 cores with `--jobs 2`, 10.2 samples/s by default, 12.5 with rasterization on the workers'
/// own threads. So unless the user set `LP_NUM_THREADS`, workers get cores / jobs threads each
/// (0 = rasterize on the calling thread). GPU drivers ignore the variable.
fn share_cores_with_lavapipe(jobs: usize) {
    if jobs <= 1 || std::env::var_os("LP_NUM_THREADS").is_some() {
        return;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let per_job = cores / jobs;
    let threads = if per_job <= 1 { 0 } else { per_job };
    // SAFETY: called in main before any other thread exists.
    unsafe { std::env::set_var("LP_NUM_THREADS", threads.to_string()) };
}

/// glibc hands freed blocks above its mmap threshold (images and readback buffers of about a
/// megabyte, every sample) back to the kernel, which then zero-fills fresh pages for the next
/// sample. Measured with `vtgen bench --jobs 1`: page faults took 5.4 ms of CPU per sample, 1.1 ms
/// with blocks up to 32 MiB kept in the heap, for 35 MiB more peak RSS. (With `--jobs 2` lavapipe
/// rasterizes on the workers' threads and faults far less either way.)
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_freed_memory() {
    // SAFETY: plain glibc tuning calls, made before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 20);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_freed_memory() {}

fn main() -> ExitCode {
    keep_freed_memory();
    quiet_headless_mesa();
    let cli = Cli::parse();
    match &cli.command {
        Command::Generate { jobs, .. } | Command::Bench { jobs, .. } => share_cores_with_lavapipe(*jobs),
        _ => {}
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let chain: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            eprintln!("error: {}", chain.join(": "));
            ExitCode::FAILURE
        }
    }
}
