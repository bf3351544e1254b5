//! `vtpose`: train, evaluate and benchmark visuotactile pose networks on vtgen datasets.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use burn::module::Module;
use clap::{Args, Parser, Subcommand};
use vt_trainer::bench::{bench_model, bench_training, table, training_table};
use vt_trainer::config::TrainConfig;
use vt_trainer::device;
use vt_trainer::eval::refined::{RefineCommand, evaluate_refined, refined_evals};
use vt_trainer::eval::{EvalCommand, evaluate_runs, run_names};
use vt_trainer::model::Variant;
use vt_trainer::report::refine::{pool_reports, write_refine_report};
use vt_trainer::report::sheet::write_sheet;
use vt_trainer::report::write_report;
use vt_trainer::sweep::{SweepOptions, sweep};
use vt_trainer::track::filter::FilterConfig;
use vt_trainer::track::report::write_tracking_report;
use vt_trainer::track::{TrackOptions, track_runs};
use vt_trainer::train::{RunDir, TrainOptions, step_threads, train};

#[derive(Parser)]
#[command(
    name = "vtpose",
    version,
    about = "Train and evaluate visuotactile 6D pose networks (Tactile-Channel, DenseFusion baseline) on vtgen datasets"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a network from a YAML config into a run directory.
    Train(TrainArgs),
    /// The paper's tactile-point experiment: train one network per tactile point count
    /// (default 4, 12, 36, 60, 240), evaluate each on the test split, write a report.
    Sweep(SweepArgs),
    /// Evaluate trained runs on a split and write a Markdown report.
    Eval(EvalArgs),
    /// Time inference (network alone, batch 1) per model, or with --train training steps
    /// (steps/s, CPU share, time per stage).
    Bench(BenchArgs),
    /// The tracking benchmark: trained runs over every frame of the test episodes of an episode
    /// dataset, scored as sequences (ADD-S AUC per episode, drift, error and occlusion against
    /// time), per frame, with a constant-velocity filter, and with another episode's touch.
    Track(TrackArgs),
    /// The geometric pose refiner on a split: from no initial pose and from each run's estimate,
    /// with the depth alone, with touch, and with another grasp's touch (the touch control);
    /// paired per grasp, by occlusion level and object, timed.
    Refine(RefineArgs),
}

#[derive(Args)]
struct RefineArgs {
    /// Trained runs (from `vtpose train`) whose estimates the refiner also starts from; none: the
    /// refiner alone.
    runs: Vec<PathBuf>,
    /// The dataset (default: the first run's).
    #[arg(long)]
    dataset: Option<PathBuf>,
    #[arg(long, default_value = "test")]
    split: String,
    /// Where refine.md, refine.json, samples-refine.csv and sheet.png go.
    #[arg(long, default_value = "out/refine")]
    out: PathBuf,
    /// At most this many samples, evenly spread over the split (0: all).
    #[arg(long, default_value_t = 0)]
    max_samples: usize,
    /// The refiner's settings (YAML, the fields of `refine:` in docs/refine.md); default: built in.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Skip the touch control (every touch estimator again with another grasp's touch).
    #[arg(long)]
    no_touch_control: bool,
    /// Draw up to this many samples where depth alone fails and touch recovers the pose (sheet.png).
    #[arg(long, default_value_t = 8)]
    sheet: usize,
    /// Threads (0: every core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Instead of refining: pool the reports of earlier `vtpose refine` runs (their output
    /// folders, e.g. one per object pair) into one report in --out.
    #[arg(long, num_args = 1.., conflicts_with_all = ["runs", "dataset"])]
    pool: Vec<PathBuf>,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct TrainArgs {
    /// The training config (YAML). With --resume it may be left out: the run's own config.yaml is used.
    #[arg(required_unless_present = "resume")]
    config: Option<PathBuf>,
    /// The run directory (default: out/runs/<config name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Use this dataset instead of the config's.
    #[arg(long)]
    dataset: Option<PathBuf>,
    /// Override the config's model variant (tactile_channel, vision_only, non_siamese, no_global, tactile_only).
    #[arg(long)]
    variant: Option<Variant>,
    /// Override the config's number of epochs: the run's total, also with --resume (a run
    /// that has done 20 epochs resumed with --epochs 30 trains 10 more).
    #[arg(long)]
    epochs: Option<usize>,
    /// Continue the run in --out from its last completed epoch (with its own config.yaml
    /// unless CONFIG is given; --epochs sets the new total).
    #[arg(long, conflicts_with = "overwrite", requires = "out")]
    resume: bool,
    /// Replace a run in --out.
    #[arg(long)]
    overwrite: bool,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct SweepArgs {
    /// The training config of a tactile variant (its data.n_tactile is replaced per run).
    config: PathBuf,
    /// Where the runs (nt-NNNN/) and the report go (default: out/sweeps/<config name>).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, value_delimiter = ',', default_values_t = vt_trainer::data::TACTILE_SWEEP)]
    counts: Vec<usize>,
    /// Use this dataset instead of the config's.
    #[arg(long)]
    dataset: Option<PathBuf>,
    /// Override the config's number of epochs (per run).
    #[arg(long)]
    epochs: Option<usize>,
    /// A trained vision-only run to evaluate alongside.
    #[arg(long)]
    baseline: Option<PathBuf>,
    /// At most this many test samples, evenly spread (0: all).
    #[arg(long, default_value_t = 0)]
    max_samples: usize,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct EvalArgs {
    /// Run directories (from `vtpose train`).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// Evaluate on this dataset instead of each run's own.
    #[arg(long)]
    dataset: Option<PathBuf>,
    #[arg(long, default_value = "test")]
    split: String,
    /// Where report.md, results.json and samples-<run>.csv go.
    #[arg(long, default_value = "out/eval")]
    out: PathBuf,
    /// At most this many samples, evenly spread over the split (0: all).
    #[arg(long, default_value_t = 0)]
    max_samples: usize,
    /// Skip evaluating tactile networks with 4, 12, 36, 60, 240 points (one network, fed
    /// fewer points; `vtpose sweep` trains one network per count as the paper).
    #[arg(long)]
    no_sweep: bool,
    /// Skip the touch control: tactile networks evaluated again with the touch of another grasp
    /// of the same object and with no touch (two more passes).
    #[arg(long)]
    no_touch_control: bool,
    /// Also each network's estimates refined by the geometric refiner, with the depth alone and
    /// with touch (two more rows per run; `vtpose refine` has the whole comparison).
    #[arg(long)]
    refine: bool,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct TrackArgs {
    /// Run directories (from `vtpose train`); none with --refine and --dataset: the refiner alone.
    #[arg(required_unless_present = "refine")]
    runs: Vec<PathBuf>,
    /// Track with the geometric refiner too: alone and from each run's estimates, warm-started
    /// from frame to frame, with depth, with touch and with another episode's touch.
    #[arg(long)]
    refine: bool,
    /// The refiner's settings (YAML; see docs/refine.md); default: built in.
    #[arg(long, requires = "refine")]
    refine_config: Option<PathBuf>,
    /// Track on this episode dataset instead of each run's own.
    #[arg(long)]
    dataset: Option<PathBuf>,
    #[arg(long, default_value = "test")]
    split: String,
    /// Where tracking.md, tracking.json, episodes.csv, frames.csv and the charts go.
    #[arg(long, default_value = "out/track")]
    out: PathBuf,
    /// At most this many episodes, evenly spread over the split (0: all).
    #[arg(long, default_value_t = 0)]
    max_episodes: usize,
    /// Skip the touch control: tactile networks fed the touch of another episode of the same
    /// object (one more pass).
    #[arg(long)]
    no_touch_control: bool,
    /// The filter's pose gain α (0 < α <= 1).
    #[arg(long, default_value_t = FilterConfig::default().alpha)]
    alpha: f64,
    /// The filter's velocity gain β (0 <= β < 2; default: Benedict-Bordner's α²/(2 − α)).
    #[arg(long, default_value_t = FilterConfig::default().beta)]
    beta: f64,
    /// The filter rejects estimates farther than this from its prediction (cm).
    #[arg(long, default_value_t = FilterConfig::default().gate_cm)]
    gate_cm: f64,
    /// The filter rejects estimates turned more than this from its prediction (degrees).
    #[arg(long, default_value_t = FilterConfig::default().gate_deg)]
    gate_deg: f64,
    /// The filter starts a new track after this many rejections in a row.
    #[arg(long, default_value_t = FilterConfig::default().reinit_after)]
    reinit_after: usize,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct BenchArgs {
    /// Run directories or config files; none: every variant with the default config.
    inputs: Vec<PathBuf>,
    /// With configs or no input: these variants (default: the config's; `all` for every one).
    #[arg(long, value_delimiter = ',')]
    variants: Vec<String>,
    #[arg(long, default_value_t = 20)]
    iters: usize,
    #[arg(long, default_value_t = 3)]
    warmup: usize,
    #[arg(long, default_value = "cpu", help = device::DEVICE_HELP)]
    device: String,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    json: bool,
    /// Time training steps instead of inference: a batch of train.batch_size through forward,
    /// loss, backward and Adam, with one thread (and its time per stage) and with the step's
    /// threads (train.step_threads; 0: every core on a CPU).
    #[arg(long)]
    train: bool,
    /// Time the geometric refiner instead, on --iters test samples of this dataset (one core and
    /// every core).
    #[arg(long, conflicts_with = "train")]
    refine: Option<PathBuf>,
}

fn main() -> ExitCode {
    vt_trainer::host::keep_freed_memory();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Train(args) => train_command(args),
        Command::Sweep(args) => sweep_command(args),
        Command::Eval(args) => eval_command(args),
        Command::Bench(args) => bench_command(args),
        Command::Track(args) => track_command(args),
        Command::Refine(args) => refine_command(args),
    }
}

fn train_command(args: TrainArgs) -> Result<()> {
    let TrainArgs { config, out, dataset, variant, epochs, resume, overwrite, device: dev, quiet } = args;
    let out = match (&out, &config) {
        (Some(o), _) => o.clone(),
        (None, Some(c)) => PathBuf::from("out/runs").join(c.file_stem().unwrap_or_default()),
        (None, None) => bail!("--resume needs --out (the run directory)"),
    };
    let mut cfg = match &config {
        Some(c) => TrainConfig::load(c)?,
        None => {
            let run = RunDir(out.clone());
            TrainConfig::load(&run.config()).with_context(|| format!("--resume without CONFIG: {} is not a run", out.display()))?
        }
    };
    if let Some(d) = dataset {
        cfg.dataset = d;
    }
    if let Some(v) = variant {
        cfg.model.variant = v;
    }
    if let Some(e) = epochs {
        cfg.train.epochs = e;
    }
    let summary = train(&cfg, &TrainOptions { out, resume, overwrite, device: device::parse(&dev)?, quiet })?;
    if !quiet {
        let last = summary.epochs.last();
        eprintln!(
            "vtpose: {} epochs done ({} steps) in {}{}",
            summary.state.epochs_done,
            summary.state.steps,
            summary.run.display(),
            last.map_or(String::new(), |r| format!(", last loss {:.5}", r.loss))
        );
    }
    Ok(())
}

fn sweep_command(args: SweepArgs) -> Result<()> {
    let SweepArgs { config, out, counts, dataset, epochs, baseline, max_samples, device: dev, quiet } = args;
    let mut cfg = TrainConfig::load(&config)?;
    if let Some(d) = dataset {
        cfg.dataset = d;
    }
    if let Some(e) = epochs {
        cfg.train.epochs = e;
    }
    let out = out.unwrap_or_else(|| PathBuf::from("out/sweeps").join(config.file_stem().unwrap_or_default()));
    let opts = SweepOptions { counts, out: out.clone(), baseline, max_samples, device: device::parse(&dev)?, quiet };
    sweep(&cfg, &opts)?;
    if !quiet {
        eprintln!("vtpose: wrote {}", out.join("report.md").display());
    }
    Ok(())
}

fn eval_command(args: EvalArgs) -> Result<()> {
    let EvalArgs { runs, dataset, split, out, max_samples, no_sweep, no_touch_control, refine, device: dev, quiet } = args;
    let device = device::parse(&dev)?;
    let cmd = EvalCommand {
        dataset,
        split: split.clone(),
        max_samples,
        sweep: !no_sweep,
        touch_control: !no_touch_control,
        device: device.clone(),
        quiet,
    };
    let mut evals = evaluate_runs(&runs, &cmd)?;
    if refine {
        let refined = refined_evals(&evals, &cmd, &vt_trainer::refine::RefineConfig::default())?;
        evals.extend(refined);
    }
    let report = write_report(&evals, &split, &dev, &out)?;
    if !quiet {
        eprintln!("vtpose: wrote {}", report.display());
    }
    print!("{}", std::fs::read_to_string(&report)?);
    Ok(())
}

fn track_command(args: TrackArgs) -> Result<()> {
    let TrackArgs {
        runs,
        refine,
        refine_config,
        dataset,
        split,
        out,
        max_episodes,
        no_touch_control,
        alpha,
        beta,
        gate_cm,
        gate_deg,
        reinit_after,
        device: dev,
        quiet,
    } = args;
    let opts = TrackOptions {
        dataset,
        split,
        max_episodes,
        filter: FilterConfig { alpha, beta, gate_cm, gate_deg, reinit_after },
        touch_control: !no_touch_control,
        refine: match (refine, refine_config) {
            (false, _) => None,
            (true, None) => Some(vt_trainer::refine::RefineConfig::default()),
            (true, Some(path)) => Some(vt_trainer::refine::RefineConfig::load(&path)?),
        },
        device: device::parse(&dev)?,
        quiet,
    };
    let tracking = track_runs(&runs, &run_names(&runs), &opts)?;
    let report = write_tracking_report(&tracking, &dev, &out)?;
    if !quiet {
        eprintln!("vtpose: wrote {}", report.display());
    }
    print!("{}", std::fs::read_to_string(&report)?);
    Ok(())
}

fn refine_command(args: RefineArgs) -> Result<()> {
    let RefineArgs { runs, dataset, split, out, max_samples, config, no_touch_control, sheet, threads, pool, device: dev, quiet } = args;
    if !pool.is_empty() {
        let eval = pool_reports(&pool)?;
        let report = write_refine_report(&eval, &out)?;
        if !quiet {
            eprintln!("vtpose: wrote {}", report.display());
        }
        print!("{}", std::fs::read_to_string(&report)?);
        return Ok(());
    }
    let dataset = match (dataset, runs.first()) {
        (Some(d), _) => d,
        (None, Some(run)) => TrainConfig::load(&RunDir(run.clone()).config()).with_context(|| format!("run {}", run.display()))?.dataset,
        (None, None) => bail!("vtpose refine needs --dataset or a run"),
    };
    let config = match config {
        Some(path) => vt_trainer::refine::RefineConfig::load(&path)?,
        None => vt_trainer::refine::RefineConfig::default(),
    };
    if threads > 0 {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().context("cannot start the refiner's threads")?;
    }
    let cmd =
        RefineCommand { dataset, split, max_samples, runs, config, touch_control: !no_touch_control, device: device::parse(&dev)?, quiet };
    let eval = evaluate_refined(&cmd)?;
    let report = write_refine_report(&eval, &out)?;
    if let Some(sheet) = write_sheet(&eval, sheet, &out)?
        && !quiet
    {
        eprintln!("vtpose: wrote {}", sheet.display());
    }
    if !quiet {
        eprintln!("vtpose: wrote {}", report.display());
    }
    print!("{}", std::fs::read_to_string(&report)?);
    Ok(())
}

/// `--variants` of `vtpose bench`: none (the config's `default`), `all`, or a list.
fn chosen_variants(variants: &[String], default: Variant) -> Result<Vec<Variant>> {
    match variants {
        [] => Ok(vec![default]),
        [a] if a == "all" => Ok(Variant::ALL.to_vec()),
        list => list.iter().map(|v| v.parse()).collect(),
    }
}

/// `vtpose bench --train`: per config (a run's own for a run directory, the default without
/// input) and variant, a one-thread step and, where the step uses more, a threaded one.
fn bench_training_command(args: BenchArgs) -> Result<()> {
    let BenchArgs { inputs, variants, iters, warmup, device: dev, json, train: _, refine: _ } = args;
    let device = device::parse(&dev)?;
    let mut configs: Vec<(String, TrainConfig)> = Vec::new();
    if inputs.is_empty() {
        configs.push(("default".into(), TrainConfig::new("")));
    }
    for input in &inputs {
        let name = input.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        let config = if input.is_dir() { RunDir(input.clone()).config() } else { input.clone() };
        if !config.is_file() {
            bail!("{} is neither a run directory nor a config file", input.display());
        }
        configs.push((name, TrainConfig::load(&config)?));
    }
    let mut rows = Vec::new();
    for (name, cfg) in &configs {
        for v in chosen_variants(&variants, cfg.model.variant)? {
            let mut cfg = cfg.clone();
            cfg.model.variant = v;
            let label = format!("{name}/{v}");
            let threads = step_threads(&cfg.train, &device);
            rows.push(bench_training(&label, &cfg, &device, 1, iters, warmup));
            if threads > 1 {
                rows.push(bench_training(&label, &cfg, &device, threads, iters, warmup));
            }
        }
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{}", training_table(&rows, &dev));
    }
    Ok(())
}

fn bench_command(args: BenchArgs) -> Result<()> {
    if args.train {
        return bench_training_command(args);
    }
    if let Some(dataset) = &args.refine {
        let rows = vt_trainer::bench::bench_refiner(dataset, args.iters, vt_trainer::refine::RefineConfig::default())?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&rows)?);
        } else {
            print!("{}", vt_trainer::bench::refine_table(&rows));
        }
        return Ok(());
    }
    let BenchArgs { inputs, variants, iters, warmup, device: dev, json, train: _, refine: _ } = args;
    let device = device::parse(&dev)?;
    let mut rows = Vec::new();
    let mut configs: Vec<(String, TrainConfig)> = Vec::new();
    if inputs.is_empty() {
        configs.push(("default".into(), TrainConfig::new("")));
        if variants.is_empty() {
            configs[0].1.model.variant = Variant::TactileChannel;
        }
    }
    for input in &inputs {
        let name = input.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        if input.is_dir() {
            let (cfg, _, model) = RunDir(input.clone()).load_model(&device).with_context(|| format!("run {}", input.display()))?;
            rows.push(bench_model(&name, &model.valid(), &cfg.data, &device, iters, warmup));
        } else if input.is_file() {
            configs.push((name, TrainConfig::load(input)?));
        } else {
            bail!("{} is neither a run directory nor a config file", input.display());
        }
    }
    let all_variants = inputs.is_empty() && variants.is_empty();
    for (name, cfg) in &configs {
        let vs = if all_variants { Variant::ALL.to_vec() } else { chosen_variants(&variants, cfg.model.variant)? };
        for v in vs {
            let mut m = cfg.model.clone();
            m.variant = v;
            let model = m.init(1, &device);
            rows.push(bench_model(&format!("{name}/{v}"), &model, &cfg.data, &device, iters, warmup));
        }
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{}", table(&rows, &dev));
    }
    Ok(())
}
