use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};
use vtgen::config::{LoadedConfig, Override};
use vtgen::output::generate::GenerateOptions;
use vtgen::plan::ShardSelector;

/// Synthetic visuotactile training data for in-hand 6D object pose estimation.
#[derive(Parser)]
#[command(name = "vtgen", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The robot's files: the folder of the packages its URDF's `package://` meshes name, as
    /// `scripts/robot-assets` fetches them (it prints the folder). The built-in robots are drawn
    /// from their real meshes with it and from their URDF's primitive shapes without it.
    /// Overrides the config's robot.assets.
    #[arg(long, global = true, value_name = "DIR")]
    robot_assets: Option<PathBuf>,
    /// Override a config key (repeatable), with the config's own checks, e.g.
    /// `--set sampling.trajectories_per_object=2 --set sampling.instances_per_trajectory=5`.
    #[arg(long = "set", global = true, value_name = "KEY=VALUE")]
    overrides: Vec<Override>,
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
        /// Continue an interrupted run: keep the shards that check out (complete, intact, this
        /// config's and generator's), redo the rest and say which and why.
        #[arg(long)]
        resume: bool,
        /// Replace a dataset that is already in the output directory.
        #[arg(long, conflicts_with = "resume")]
        overwrite: bool,
        /// Continue a dataset that another vtgen build started (refused otherwise: its shards
        /// would differ in how they were made).
        #[arg(long)]
        mix_generators: bool,
        /// Generate nothing: rebuild the manifest from the shards on disk, and fail naming the
        /// missing ones (a cluster's merge step).
        #[arg(long, conflicts_with = "overwrite")]
        manifest_only: bool,
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
    /// Print the config as vtgen reads it: every default filled in and `--set` applied (YAML).
    Config { config: PathBuf },
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
        /// Also print the samples/s N cores would give if rendering cost them nothing (a GPU
        /// rasterizes): N divided by the measured CPU time per sample outside the rasterizer.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
        predict_cores: Option<u32>,
        /// Also time every render pass on its own (shadow map, main views, anti-aliased colour,
        /// mask views, depth views, optical shading, copy and map, readback): each is submitted
        /// and waited for, so the run is slower than without; the images are the same.
        #[arg(long)]
        per_pass: bool,
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
        /// Run the hold screen as a judge only: every attempt goes on whatever the screen finds,
        /// and its verdicts are counted against the attempts' outcomes (how many failures it
        /// catches, how many held grasps it would turn away).
        #[arg(long)]
        judge_screen: bool,
    },
    /// Check the robot a config names before making data.
    Robot {
        #[command(subcommand)]
        action: RobotAction,
    },
    /// Optical tactile sensors: fit one to a real unit.
    Tactile {
        #[command(subcommand)]
        action: TactileAction,
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
enum TactileAction {
    /// Fits an optical sensor (pixel size, light model, background) to a folder of a real unit's
    /// images: `background.png` (or `bg.png`, nothing touching the gel) and presses of a ball of
    /// known radius at several places. Writes `calibration.yaml` (and the background PNG) for
    /// `robot.tactile.optical.calibration`, and reports the fit's residual per image.
    Calibrate {
        dir: PathBuf,
        /// The ball's radius (mm).
        #[arg(long)]
        ball_radius: f64,
        /// The pixel size (mm) on the gel, measured on the unit; without it, identified from the
        /// presses when their shape fixes it, refused otherwise.
        #[arg(long)]
        pixel_size_mm: Option<f64>,
        /// The printed markers' pitch (mm; the gel's datasheet, or a caliper across ten of them):
        /// the pixel size is that over the markers' period in the background image.
        #[arg(long, conflicts_with = "pixel_size_mm")]
        marker_pitch_mm: Option<f64>,
        /// Keep K presses (spread over the sorted names) out of the fit, render them through it
        /// and report their residual over the whole contact disc against "no change".
        #[arg(long, default_value_t = 0)]
        holdout: usize,
        /// Where the calibration goes (default: DIR/calibration).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Renders a ball press (or a height map of the gel) through a calibration, vtgen's
    /// `calibration.yaml` or Taxim's `polycalib.npz`, into a PNG: noise-free, no markers, to set
    /// beside a real frame of the same press.
    RenderPress {
        calibration: PathBuf,
        /// The ball's radius (mm).
        #[arg(long, required_unless_present = "height_map")]
        ball_radius: Option<f64>,
        /// How deep the ball presses into the gel (mm).
        #[arg(long, required_unless_present = "height_map")]
        depth_mm: Option<f64>,
        /// The ball's centre in the image, `COLUMN,ROW` in pixels from the image's corner
        /// (default: the image's centre).
        #[arg(long, value_delimiter = ',')]
        at: Option<Vec<f64>>,
        /// The pixel size (mm): needed for Taxim's files, which do not give it.
        #[arg(long)]
        pixel_size_mm: Option<f64>,
        /// A height map of the gel's indentation (`.npy`, rows x columns of the calibration's
        /// image) in place of the ball: larger values pushed further in.
        #[arg(long, conflicts_with_all = ["ball_radius", "depth_mm", "at"])]
        height_map: Option<PathBuf>,
        /// The height map's unit: `mm`, or `pixels` (of --pixel-size-mm; Taxim's height maps).
        #[arg(long, default_value = "mm")]
        height_unit: String,
        /// The PNG to write.
        #[arg(long, short)]
        out: PathBuf,
    },
}

#[derive(Subcommand)]
enum RobotAction {
    /// Loads every link's geometry (all problems at once), then draws grasp-frame poses from the
    /// workspace: the share the arm reaches, links under the floor, arm joints at a limit, a
    /// gripper's jaws facing each other. Exit status 1 when a problem is found.
    Check {
        config: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Search a home, a workspace height and a base distance with which the check passes
        /// (the smallest change first) and print them as `--set` lines, with the figures before
        /// and after.
        #[arg(long)]
        suggest: bool,
        /// A parallel-jaw gripper's pads pass when their normals are within this many degrees of
        /// opposite at some opening between the preshape and the closing target.
        #[arg(long, default_value_t = vtgen::cli::robot_check::JAW_TOLERANCE_DEG)]
        jaw_tolerance_deg: f64,
        /// After a passing check, a short hold test: this many trajectories per object through
        /// the grasp loop (2 instances each; `vtgen grasps`' table), failing when an object keeps
        /// fewer than half of them.
        #[arg(long, value_name = "TRAJECTORIES", default_value_t = 0)]
        hold: u32,
        /// Also write a picture (PNG) of the collision shapes and pad frames over the robot, at
        /// home and in a grasp the config makes.
        #[arg(long, value_name = "FILE")]
        picture: Option<PathBuf>,
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
        /// List a test image in test_targets_bop19/24.json when its object is visible at least
        /// this fraction (BOP's datasets use 0.1; default: any visible pixel).
        #[arg(long, default_value_t = 0.0)]
        targets_min_visib: f64,
    },
    /// A LeRobotDataset v3.0 (parquet frames, the camera and optical tactile images as videos),
    /// written by LeRobot's own writer through `python3 -m vtdata.lerobot`; episodes at one rate
    /// (each stream's latest reading at or before each frame), snapshots as one-frame episodes.
    Lerobot {
        dataset: PathBuf,
        /// A new (or empty) directory.
        #[arg(long)]
        out: PathBuf,
        /// LeRobot's repo id, <owner>/<name> (default: vtgen/<dataset folder name>).
        #[arg(long)]
        repo_id: Option<String>,
        /// Frames per second, a whole number of physics steps (default: the camera's rate; 10 for
        /// snapshots).
        #[arg(long)]
        fps: Option<u32>,
        /// LeRobot's video codec (libsvtav1, h264, hevc).
        #[arg(long, default_value = "libsvtav1")]
        vcodec: String,
        /// The Python interpreter with vtdata and lerobot (default: $VTGEN_PYTHON, else python3).
        #[arg(long)]
        python: Option<PathBuf>,
        /// No progress lines.
        #[arg(long)]
        quiet: bool,
    },
}

impl ExportFormat {
    /// The dataset, the output folder and the format's exporter.
    fn exporter(self) -> (PathBuf, PathBuf, Box<dyn vtgen::cli::export::Exporter>) {
        use vtgen::cli::export::{Bop, BopOptions, LerobotOptions};
        match self {
            ExportFormat::Bop { dataset, out, quiet, exr, targets_min_visib } => {
                (dataset, out, Box::new(Bop { quiet, options: BopOptions { exr, targets_min_visib } }))
            }
            ExportFormat::Lerobot { dataset, out, repo_id, fps, vcodec, python, quiet } => {
                (dataset, out, Box::new(LerobotOptions { repo_id, fps, vcodec, python, quiet }))
            }
        }
    }
}

// A table: one match arm per subcommand, from parsed flags to its `vtgen::cli::<command>::run`.
fn run(cli: Cli) -> Result<()> {
    let load = |config: &PathBuf| anyhow::Ok(LoadedConfig::load_with_assets(config, &cli.overrides, cli.robot_assets.as_deref())?);
    let reads_config = matches!(
        cli.command,
        Command::Generate { .. }
            | Command::Plan { .. }
            | Command::Config { .. }
            | Command::Bench { .. }
            | Command::Grasps { .. }
            | Command::Robot { .. }
            | Command::Preview { .. }
    );
    anyhow::ensure!(reads_config || cli.overrides.is_empty(), "--set overrides a config's keys, and this command reads a dataset");
    use vtgen::cli as commands;
    match cli.command {
        Command::Generate { config, out, shard, resume, overwrite, mix_generators, manifest_only, jobs, ycb_dir, quiet } => {
            let cfg = load(&config)?;
            let out = out.unwrap_or_else(|| cfg.config.output.dir.clone());
            let opts = GenerateOptions {
                out,
                shard: shard.unwrap_or(ShardSelector::ALL),
                resume: resume || manifest_only,
                overwrite,
                jobs,
                quiet,
                ycb_dir,
                mix_generators,
                manifest_only,
            };
            commands::generate::run(&cfg, &opts)
        }
        Command::Plan { config } => {
            commands::plan::run(&config, &load(&config)?);
            Ok(())
        }
        Command::Config { config } => commands::plan::run_config(&load(&config)?),
        Command::Bench { config, samples, jobs, ycb_dir, json, predict_cores, per_pass } => {
            let options =
                commands::bench::BenchOptions { samples, jobs, ycb_dir, predict_cores: predict_cores.map(|n| n as usize), per_pass };
            commands::bench::run(&load(&config)?, &options, json)
        }
        Command::Grasps { config, trajectories, instances, jobs, ycb_dir, min_kept, json, quiet, judge_screen } => {
            let jobs = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let opts = commands::grasps::GraspCheckOptions { trajectories, instances, jobs, quiet, judge_screen };
            commands::grasps::run(&load(&config)?, ycb_dir.as_ref(), &opts, json, min_kept)
        }
        Command::Tactile { action: TactileAction::Calibrate { dir, ball_radius, pixel_size_mm, marker_pitch_mm, holdout, out } } => {
            let out = out.unwrap_or_else(|| dir.join("calibration"));
            commands::tactile::calibrate(&dir, ball_radius, pixel_size_mm, marker_pitch_mm, holdout, &out)
        }
        Command::Tactile {
            action: TactileAction::RenderPress { calibration, ball_radius, depth_mm, at, pixel_size_mm, height_map, height_unit, out },
        } => {
            use commands::tactile::{PressShape, read_height_map, render_press_image};
            if let Some(a) = at.as_ref().filter(|a| a.len() != 2) {
                anyhow::bail!("--at {}: give the centre as COLUMN,ROW (two numbers, pixels)", a.len());
            }
            let shape = match height_map {
                Some(path) => PressShape::HeightMap(read_height_map(&path, &height_unit, pixel_size_mm)?),
                None => PressShape::Ball {
                    radius_mm: ball_radius.expect("clap requires it"),
                    depth_mm: depth_mm.expect("clap requires it"),
                    centre_px: at.map(|a| [a[0], a[1]]),
                },
            };
            render_press_image(&calibration, pixel_size_mm, shape, &out)
        }
        Command::Robot { action: RobotAction::Check { config, json, suggest, jaw_tolerance_deg, hold, picture } } => {
            anyhow::ensure!(
                (0.0..=90.0).contains(&jaw_tolerance_deg),
                "--jaw-tolerance-deg: {jaw_tolerance_deg} is not within 0 ..= 90 degrees"
            );
            let cfg = load(&config)?;
            // The picture first: it shows what is wrong when the check finds a problem.
            if let Some(out) = &picture {
                commands::robot_picture::write(&cfg, None, out)?;
            }
            if suggest {
                commands::robot_suggest::run(&cfg, json, jaw_tolerance_deg)?;
            } else {
                commands::robot_check::run(&cfg, json, jaw_tolerance_deg)?;
            }
            if hold > 0 && !suggest {
                let jobs = std::thread::available_parallelism().map_or(1, |n| n.get());
                let opts =
                    commands::grasps::GraspCheckOptions { trajectories: hold, instances: Some(2), jobs, quiet: true, judge_screen: false };
                println!("hold test: {hold} trajectories per object, 2 instances each");
                commands::grasps::run(&cfg, None, &opts, json, Some(0.5))?;
            }
            Ok(())
        }
        Command::Preview { source, n, out, width, columns, ycb_dir } => {
            commands::preview::run(&source, n, &out, (width, columns), ycb_dir.as_ref(), cli.robot_assets.clone(), &cli.overrides)
        }
        Command::Inspect { dataset, json } => commands::inspect::run(&dataset, json),
        Command::Validate { dataset, full } => commands::validate::run(&dataset, full),
        Command::Stats { dataset, out } => commands::stats::run(&dataset, &out),
        Command::Export { format } => {
            let (dataset, out, exporter) = format.exporter();
            commands::export::run(exporter.as_ref(), &dataset, &out)
        }
        Command::Dump { dataset, split, index, out, exr } => commands::dump::dump(&dataset, &split, index, &out, exr),
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
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
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
