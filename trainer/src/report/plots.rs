//! The report's pictures, as standalone SVG (any browser, GitHub and the README show them): errors
//! by occlusion bin and by object (bars with standard-error whiskers, one colour per run), and the
//! paired per-grasp comparison (one dot per grasp: baseline error against tactile error; below
//! the diagonal touch helped).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};

use crate::eval::{ModelEval, Summary, comparisons};
use crate::metrics::{MeanSe, OcclusionBin};

const COLORS: [&str; 6] = ["#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860"];
const W: f64 = 720.0;
const H: f64 = 360.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 70.0;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A "nice" axis maximum and tick step for values up to `max`.
fn nice_axis(max: f64) -> (f64, f64) {
    let max = if max.is_finite() && max > 0.0 { max } else { 1.0 };
    let raw = max / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    ((max / step).ceil() * step, step)
}

fn header(title: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#, W / 2.0, esc(title));
    s
}

fn y_axis(s: &mut String, y_max: f64, step: f64, label: &str) -> impl Fn(f64) -> f64 + use<> {
    let plot_h = H - TOP - BOTTOM;
    let y = move |v: f64| TOP + plot_h * (1.0 - v / y_max);
    let mut v = 0.0;
    while v <= y_max + 1e-9 {
        let _ = writeln!(
            s,
            r##"<line x1="{LEFT}" x2="{}" y1="{1:.1}" y2="{1:.1}" stroke="#ddd"/><text x="{2}" y="{3:.1}" text-anchor="end">{4}</text>"##,
            W - RIGHT,
            y(v),
            LEFT - 6.0,
            y(v) + 4.0,
            trim(v)
        );
        v += step;
    }
    let _ = writeln!(s, r#"<text transform="translate(18,{}) rotate(-90)" text-anchor="middle">{}</text>"#, TOP + plot_h / 2.0, esc(label));
    let _ = writeln!(s, r#"<line x1="{LEFT}" x2="{LEFT}" y1="{TOP}" y2="{}" stroke="black"/>"#, H - BOTTOM);
    y
}

fn trim(v: f64) -> String {
    let t = format!("{v:.3}");
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Grouped bars: one group per label, one bar per series (mean with a standard-error whisker).
pub fn bar_chart(title: &str, y_label: &str, groups: &[String], series: &[(String, Vec<MeanSe>)]) -> String {
    let mut s = header(title);
    let top = series.iter().flat_map(|(_, v)| v.iter().filter(|m| m.n > 0).map(|m| m.mean + m.se)).fold(0.0, f64::max);
    let (y_max, step) = nice_axis(top * 1.05);
    let y = y_axis(&mut s, y_max, step, y_label);
    let plot_w = W - LEFT - RIGHT;
    let group_w = plot_w / groups.len().max(1) as f64;
    let bar_w = 0.8 * group_w / series.len().max(1) as f64;
    for (g, label) in groups.iter().enumerate() {
        let x0 = LEFT + g as f64 * group_w + 0.1 * group_w;
        for (k, (_, values)) in series.iter().enumerate() {
            let Some(m) = values.get(g).filter(|m| m.n > 0 && m.mean.is_finite()) else { continue };
            let x = x0 + k as f64 * bar_w;
            let color = COLORS[k % COLORS.len()];
            let _ = writeln!(
                s,
                r#"<rect x="{x:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{color}"><title>{} ± {} (n = {})</title></rect>"#,
                y(m.mean),
                bar_w * 0.92,
                y(0.0) - y(m.mean),
                trim(m.mean),
                trim(m.se),
                m.n
            );
            let cx = x + bar_w * 0.46;
            let _ = writeln!(
                s,
                r#"<line x1="{cx:.1}" x2="{cx:.1}" y1="{:.1}" y2="{:.1}" stroke="black"/>"#,
                y((m.mean + m.se).min(y_max)),
                y((m.mean - m.se).max(0.0))
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{}" text-anchor="middle">{}</text>"#,
            LEFT + (g as f64 + 0.5) * group_w,
            H - BOTTOM + 16.0,
            esc(label)
        );
    }
    let _ = writeln!(s, r#"<line x1="{LEFT}" x2="{}" y1="{1:.1}" y2="{1:.1}" stroke="black"/>"#, W - RIGHT, y(0.0));
    legend(&mut s, series.iter().map(|(n, _)| n.as_str()));
    s.push_str("</svg>\n");
    s
}

fn legend<'a>(s: &mut String, names: impl Iterator<Item = &'a str>) {
    let mut x = LEFT;
    for (k, name) in names.enumerate() {
        let _ = writeln!(
            s,
            r#"<rect x="{x:.1}" y="{}" width="12" height="12" fill="{}"/><text x="{:.1}" y="{}">{}</text>"#,
            H - 30.0,
            COLORS[k % COLORS.len()],
            x + 16.0,
            H - 20.0,
            esc(name)
        );
        x += 30.0 + 7.0 * name.chars().count() as f64;
    }
}

/// One dot per grasp: the baseline's error (x) against the tactile network's (y), with the
/// diagonal; dots below it are grasps on which touch helped.
pub fn paired_scatter(title: &str, unit: &str, points: &[(f64, f64)], x_name: &str, y_name: &str) -> String {
    let mut s = header(title);
    let top = points.iter().flat_map(|&(a, b)| [a, b]).fold(0.0, f64::max);
    let (max, step) = nice_axis(top * 1.05);
    let y = y_axis(&mut s, max, step, &format!("{y_name} ({unit})"));
    let plot_w = W - LEFT - RIGHT;
    let x = |v: f64| LEFT + plot_w * v / max;
    let mut v = 0.0;
    while v <= max + 1e-9 {
        let _ = writeln!(s, r#"<text x="{:.1}" y="{}" text-anchor="middle">{}</text>"#, x(v), H - BOTTOM + 16.0, trim(v));
        v += step;
    }
    let _ = writeln!(s, r#"<line x1="{LEFT}" x2="{}" y1="{1:.1}" y2="{1:.1}" stroke="black"/>"#, W - RIGHT, y(0.0));
    let _ = writeln!(
        s,
        r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="grey" stroke-dasharray="4 3"/>"#,
        x(0.0),
        y(0.0),
        x(max),
        y(max)
    );
    for &(a, b) in points {
        let color = if b < a { COLORS[2] } else { COLORS[3] };
        let _ = writeln!(s, r#"<circle cx="{:.1}" cy="{:.1}" r="3.5" fill="{color}" fill-opacity="0.8"/>"#, x(a), y(b));
    }
    let _ =
        writeln!(s, r#"<text x="{}" y="{}" text-anchor="middle">{} ({unit})</text>"#, LEFT + plot_w / 2.0, H - BOTTOM + 34.0, esc(x_name));
    let below = points.iter().filter(|(a, b)| b < a).count();
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" fill="{}">below the diagonal (touch better): {below} of {}</text>"#,
        LEFT + 10.0,
        TOP + 16.0,
        COLORS[2],
        points.len()
    );
    s.push_str("</svg>\n");
    s
}

/// One figure of a summary (position, angle, ...).
type Metric = fn(&Summary) -> MeanSe;

/// Writes `occlusion.svg`, `objects.svg` and, with a tactile and a vision-only run, `paired-*.svg`.
pub fn write_plots(evals: &[ModelEval], out: &Path) -> Result<()> {
    let write = |name: &str, svg: String| {
        let p = out.join(name);
        std::fs::write(&p, svg).with_context(|| format!("cannot write {}", p.display()))
    };
    let names: Vec<String> = evals.iter().map(|e| format!("{} ({})", e.name, e.variant.name())).collect();
    // By occlusion bin (and overall).
    let mut groups = vec!["all".to_string()];
    groups.extend(OcclusionBin::ALL.iter().map(|b| b.label().to_string()));
    let bins = |e: &ModelEval, f: Metric| -> Vec<MeanSe> {
        std::iter::once(f(&Summary::of(&e.results)))
            .chain(
                OcclusionBin::ALL.iter().map(|b| f(&Summary::of(e.results.iter().filter(|r| OcclusionBin::of(r.occlusion) == Some(*b))))),
            )
            .collect()
    };
    let series = |f: Metric, by: &dyn Fn(&ModelEval, Metric) -> Vec<MeanSe>| {
        evals.iter().zip(&names).map(|(e, n)| (n.clone(), by(e, f))).collect::<Vec<_>>()
    };
    write(
        "occlusion-position.svg",
        bar_chart("Position error by occlusion level", "position error (cm)", &groups, &series(|s| s.position_cm, &bins)),
    )?;
    write("occlusion-angle.svg", bar_chart("Angle error by occlusion level", "angle error (°)", &groups, &series(|s| s.angle_deg, &bins)))?;
    // By object.
    let objects: Vec<String> = evals
        .iter()
        .flat_map(|e| e.results.iter().map(|r| r.object.clone()))
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let per_object = |e: &ModelEval, f: Metric| -> Vec<MeanSe> {
        objects.iter().map(|o| f(&Summary::of(e.results.iter().filter(|r| &r.object == o)))).collect()
    };
    write(
        "objects-position.svg",
        bar_chart("Position error by object", "position error (cm)", &objects, &series(|s| s.position_cm, &per_object)),
    )?;
    // Paired per grasp.
    for (t, v) in comparisons(evals) {
        if let Some(p) = crate::compare::paired(&t.results, &v.results) {
            let pts: Vec<(f64, f64)> = p.grasps.iter().map(|g| (g.vision_position_cm, g.tactile_position_cm)).collect();
            write(
                &format!("paired-{}-vs-{}.svg", t.name, v.name),
                paired_scatter(
                    &format!("Mean position error per grasp: {} vs {}", t.name, v.name),
                    "cm",
                    &pts,
                    &format!("{} (vision only)", v.name),
                    &t.name,
                ),
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bars_scale_to_the_data_and_the_svg_is_well_formed() {
        let m = |mean: f64| MeanSe { mean, se: 0.1, n: 10 };
        let svg =
            bar_chart("t", "cm", &["a".into(), "b".into()], &[("x".into(), vec![m(1.0), m(3.0)]), ("y".into(), vec![m(2.0), m(0.5)])]);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Four bars with their whiskers, legend squares besides.
        assert_eq!(svg.matches("<title>").count(), 4);
        assert_eq!(nice_axis(3.1 * 1.05), (4.0, 1.0));
        assert_eq!(nice_axis(0.9), (1.0, 0.2));
        let sc = paired_scatter("t", "cm", &[(1.0, 0.5), (1.0, 2.0)], "v", "t");
        assert!(sc.contains("1 of 2"));
    }
}
