//! `metrics.csv` of a run directory: one row per epoch. The header and every row come from one
//! table of columns ([`COLUMNS`]), so a cell cannot drift from its header; readers find columns
//! by name ([`crate::run::RunDir::learning_curve`]).

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};

use super::EpochRecord;
use crate::eval::Summary;

/// One column: its header and how an epoch's record fills its cell.
pub struct Column {
    pub name: &'static str,
    pub cell: fn(&EpochRecord) -> String,
}

/// The columns of `metrics.csv`, in order. The `eval_*` cells are empty in epochs that did not
/// evaluate.
pub const COLUMNS: [Column; 14] = [
    Column { name: "epoch", cell: |r| r.epoch.to_string() },
    Column { name: "steps", cell: |r| r.steps.to_string() },
    Column { name: "samples", cell: |r| r.samples.to_string() },
    Column { name: "skipped", cell: |r| r.skipped.to_string() },
    Column { name: "loss", cell: |r| format!("{:.6}", r.loss) },
    Column { name: "distance_cm", cell: |r| format!("{:.4}", r.distance_cm) },
    Column { name: "seconds", cell: |r| format!("{:.2}", r.seconds) },
    Column { name: "eval_n", cell: |r| r.eval.as_ref().map_or(String::new(), |e| e.n.to_string()) },
    Column { name: "eval_position_cm", cell: |r| eval_cell(r, |e| e.position_cm.mean) },
    Column { name: "eval_angle_deg", cell: |r| eval_cell(r, |e| e.angle_deg.mean) },
    Column { name: "eval_add_auc", cell: |r| eval_cell(r, |e| e.add_auc) },
    Column { name: "eval_adds_auc", cell: |r| eval_cell(r, |e| e.adds_auc) },
    Column { name: "eval_position_median_cm", cell: |r| eval_cell(r, |e| e.position_median_cm) },
    Column { name: "eval_angle_median_deg", cell: |r| eval_cell(r, |e| e.angle_median_deg) },
];

/// A held-out metric's cell: six decimals, empty when the epoch did not evaluate.
fn eval_cell(record: &EpochRecord, metric: fn(&Summary) -> f64) -> String {
    record.eval.as_ref().map_or(String::new(), |e| format!("{:.6}", metric(e)))
}

/// The header line (without its newline).
pub fn header() -> String {
    COLUMNS.iter().map(|c| c.name).collect::<Vec<_>>().join(",")
}

/// The row of `record` (without its newline).
pub fn row(record: &EpochRecord) -> String {
    COLUMNS.iter().map(|c| (c.cell)(record)).collect::<Vec<_>>().join(",")
}

/// Opens `metrics.csv` to append rows: a `fresh` run's starts anew with the header, a resumed
/// run's keeps the rows of the epochs it has done.
pub fn open(path: &Path, fresh: bool) -> Result<std::fs::File> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(!fresh)
        .write(true)
        .truncate(fresh)
        .open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    if fresh {
        writeln!(f, "{}", header())?;
    }
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::metrics::MeanSe;
    use crate::run::RunDir;

    fn summary() -> Summary {
        let m = |mean: f64| MeanSe { mean, se: 0.1, n: 3 };
        Summary {
            n: 3,
            position_cm: m(4.5),
            angle_deg: m(118.0),
            position_median_cm: 4.25,
            angle_median_deg: 124.5,
            angle_sym_deg: m(20.0),
            add_cm: m(5.0),
            adds_cm: m(2.0),
            add_auc: 30.0,
            adds_auc: 70.5,
            accuracy_2cm: 10.0,
            tactile_chosen: 50.0,
        }
    }

    fn record(epoch: usize, eval: Option<Summary>) -> EpochRecord {
        EpochRecord {
            epoch,
            steps: 10 * epoch as u64,
            samples: 160,
            skipped: 1,
            loss: 0.0512345678,
            distance_cm: 9.87654,
            seconds: 3.456,
            eval,
        }
    }

    #[test]
    fn rows_follow_the_header_and_the_learning_curve_reads_them_back() {
        assert_eq!(
            header(),
            "epoch,steps,samples,skipped,loss,distance_cm,seconds,eval_n,eval_position_cm,eval_angle_deg,eval_add_auc,eval_adds_auc,eval_position_median_cm,eval_angle_median_deg"
        );
        assert_eq!(
            row(&record(1, Some(summary()))),
            "1,10,160,1,0.051235,9.8765,3.46,3,4.500000,118.000000,30.000000,70.500000,4.250000,124.500000"
        );
        assert_eq!(row(&record(2, None)), "2,20,160,1,0.051235,9.8765,3.46,,,,,,,");
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir(dir.path().to_path_buf());
        let mut f = open(&run.metrics(), true).unwrap();
        for r in [record(1, Some(summary())), record(2, None)] {
            writeln!(f, "{}", row(&r)).unwrap();
        }
        drop(f);
        let curve = run.learning_curve().unwrap();
        assert_eq!(curve.len(), 1);
        let p = &curve[0];
        assert_eq!((p.epoch, p.steps, p.n), (1, 10, 3));
        assert_eq!((p.position_cm, p.angle_deg, p.position_median_cm, p.angle_median_deg), (4.5, 118.0, 4.25, 124.5));
        // A resumed run appends.
        let mut f = open(&run.metrics(), false).unwrap();
        writeln!(f, "{}", row(&record(3, None))).unwrap();
        drop(f);
        assert_eq!(std::fs::read_to_string(run.metrics()).unwrap().lines().count(), 4);
    }
}
