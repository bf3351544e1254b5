//! The report's pictures, drawn with plotters as standalone SVG (any browser, GitHub and the README
//! show them): errors by occlusion bin and by object (bars with standard-error whiskers and the
//! sample count above each, one colour per run), the learning curves (held-out errors against
//! epoch), and the paired per-grasp comparison (one dot per grasp: baseline error against tactile
//! error; below the diagonal touch helped).

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use vt_dataset::OcclusionBin;

use crate::eval::compare::Comparison;
use crate::eval::metrics::MeanSe;
use crate::eval::{ModelEval, Summary};
use crate::run::CurvePoint;

/// One colour per run (seaborn's "deep" palette); the scatter's dots: green where touch helped,
/// red where it did not.
const COLORS: [RGBColor; 6] = [
    RGBColor(0x4c, 0x72, 0xb0),
    RGBColor(0xdd, 0x84, 0x52),
    RGBColor(0x55, 0xa8, 0x68),
    RGBColor(0xc4, 0x4e, 0x52),
    RGBColor(0x81, 0x72, 0xb3),
    RGBColor(0x93, 0x78, 0x60),
];
const SIZE: (u32, u32) = (720, 360);
/// The strip under a bar chart that holds the legend.
const LEGEND_H: u32 = 30;
const FONT: &str = "sans-serif";

/// plotters' errors carry the backend's error type; one message is all a user needs.
fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing a chart: {e}")
}

/// A "nice" axis maximum and tick step for values up to `max`.
fn nice_axis(max: f64) -> (f64, f64) {
    let max = if max.is_finite() && max > 0.0 { max } else { 1.0 };
    let raw = max / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    ((max / step).ceil() * step, step)
}

/// Ticks from 0 to `max` every `step`.
fn tick_count(max: f64, step: f64) -> usize {
    (max / step).round() as usize + 1
}

/// A tick label without trailing zeros (`2.5`, `4`).
fn trim(v: &f64) -> String {
    let t = format!("{v:.3}");
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Grouped bars: one group per label, one bar per series (mean with a standard-error whisker,
/// the number of samples above it).
pub fn bar_chart(title: &str, y_label: &str, groups: &[String], series: &[(String, Vec<MeanSe>)]) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (plot, legend_strip) = root.split_vertically(SIZE.1 - LEGEND_H);
        draw_bars(&plot, title, y_label, groups, series)?;
        legend(&legend_strip, series.iter().map(|(name, _)| name.as_str()))?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

fn draw_bars(
    area: &DrawingArea<SVGBackend, Shift>,
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[(String, Vec<MeanSe>)],
) -> Result<()> {
    let top = series.iter().flat_map(|(_, v)| v.iter().filter(|m| m.n > 0).map(|m| m.mean + m.se)).fold(0.0, f64::max);
    let (y_max, step) = nice_axis(top * 1.05);
    let n_groups = groups.len().max(1);
    // Group g is centred on x = g; its bars share 80 % of the unit width.
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 16))
        .margin(10)
        .x_label_area_size(24)
        .y_label_area_size(56)
        .build_cartesian_2d(-0.5..n_groups as f64 - 0.5, 0.0..y_max)
        .map_err(plot_err)?;
    let group_label = |x: &f64| {
        let g = x.round();
        if (x - g).abs() < 1e-6 && g >= 0.0 { groups.get(g as usize).cloned().unwrap_or_default() } else { String::new() }
    };
    chart
        .configure_mesh()
        .disable_x_mesh()
        .light_line_style(TRANSPARENT)
        .x_labels(n_groups)
        .x_label_formatter(&group_label)
        .y_labels(tick_count(y_max, step))
        .y_label_formatter(&trim)
        .y_desc(y_label)
        .draw()
        .map_err(plot_err)?;
    let bar_w = 0.8 / series.len().max(1) as f64;
    for (k, (_, values)) in series.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        let bars: Vec<(f64, &MeanSe)> = values
            .iter()
            .enumerate()
            .filter(|(_, m)| m.n > 0 && m.mean.is_finite())
            .map(|(g, m)| (g as f64 - 0.4 + k as f64 * bar_w, m))
            .collect();
        let centre = |x: f64| x + 0.46 * bar_w;
        chart
            .draw_series(bars.iter().map(|&(x, m)| Rectangle::new([(x, 0.0), (x + 0.92 * bar_w, m.mean)], color.filled())))
            .map_err(plot_err)?;
        let whisker_top = |m: &MeanSe| (m.mean + m.se).min(y_max);
        chart
            .draw_series(
                bars.iter()
                    .map(|&(x, m)| PathElement::new(vec![(centre(x), (m.mean - m.se).max(0.0)), (centre(x), whisker_top(m))], BLACK)),
            )
            .map_err(plot_err)?;
        let count_style = TextStyle::from((FONT, 10)).pos(Pos::new(HPos::Center, VPos::Bottom));
        chart
            .draw_series(
                bars.iter().map(|&(x, m)| {
                    EmptyElement::at((centre(x), whisker_top(m))) + Text::new(m.n.to_string(), (0, -2), count_style.clone())
                }),
            )
            .map_err(plot_err)?;
    }
    Ok(())
}

/// A colour square and the name of each series, left to right; what the numbers above the bars
/// are, on the right.
fn legend<'a>(area: &DrawingArea<SVGBackend, Shift>, names: impl Iterator<Item = &'a str>) -> Result<()> {
    let entries: Vec<(String, RGBColor)> = names.enumerate().map(|(k, n)| (n.to_string(), COLORS[k % COLORS.len()])).collect();
    legend_entries(area, &entries, "above each bar: samples")
}

/// A colour square and a name per entry, left to right, and `note` on the right.
fn legend_entries(area: &DrawingArea<SVGBackend, Shift>, entries: &[(String, RGBColor)], note: &str) -> Result<()> {
    let style = TextStyle::from((FONT, 12)).pos(Pos::new(HPos::Left, VPos::Center));
    let mut x = 70;
    for (name, color) in entries {
        area.draw(&Rectangle::new([(x, 9), (x + 12, 21)], color.filled())).map_err(plot_err)?;
        area.draw(&Text::new(name.clone(), (x + 16, 15), style.clone())).map_err(plot_err)?;
        x += 30 + 7 * name.chars().count() as i32;
    }
    let note_style = TextStyle::from((FONT, 10)).pos(Pos::new(HPos::Right, VPos::Center));
    area.draw(&Text::new(note.to_string(), (SIZE.0 as i32 - 12, 15), note_style)).map_err(plot_err)?;
    Ok(())
}

/// One line of a [`line_chart`]: `(x, y)` points in order, the palette colour `color`, dashed
/// for a second statistic of the same run.
#[derive(Debug, Clone)]
pub struct Curve {
    pub name: String,
    pub color: usize,
    pub dashed: bool,
    pub points: Vec<(f64, f64)>,
}

/// Lines with a dot at every point (learning curves: error against epoch), the y axis from 0, and
/// a grey dashed horizontal line per `references` entry (`(label, y)`; an empty label: the line alone).
pub fn line_chart(title: &str, x_label: &str, y_label: &str, curves: &[Curve], references: &[(String, f64)]) -> Result<String> {
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let x_top = curves.iter().flat_map(|c| c.points.iter().filter(finite).map(|p| p.0)).fold(1.0, f64::max);
    let y_top =
        curves.iter().flat_map(|c| c.points.iter().filter(finite).map(|p| p.1)).chain(references.iter().map(|r| r.1)).fold(0.0, f64::max);
    let (y_max, step) = nice_axis(y_top * 1.05);
    let grey = RGBColor(128, 128, 128);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        // Two legend rows: three runs with two statistics each do not fit on one.
        let (plot, legend_strip) = root.split_vertically(SIZE.1 - 2 * LEGEND_H);
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, (FONT, 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..x_top, 0.0..y_max)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .light_line_style(TRANSPARENT)
            .y_labels(tick_count(y_max, step))
            .y_label_formatter(&trim)
            .x_label_formatter(&trim)
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()
            .map_err(plot_err)?;
        let label = TextStyle::from((FONT, 11)).color(&grey).pos(Pos::new(HPos::Right, VPos::Bottom));
        for (name, y) in references {
            chart.draw_series(DashedLineSeries::new([(0.0, *y), (x_top, *y)], 3, 4, grey.into())).map_err(plot_err)?;
            if name.is_empty() {
                continue;
            }
            chart
                .draw_series(std::iter::once(EmptyElement::at((x_top, *y)) + Text::new(name.clone(), (-4, -3), label.clone())))
                .map_err(plot_err)?;
        }
        for c in curves {
            let color = COLORS[c.color % COLORS.len()];
            let pts: Vec<(f64, f64)> = c.points.iter().filter(finite).copied().collect();
            if c.dashed {
                chart.draw_series(DashedLineSeries::new(pts.clone(), 6, 4, color.stroke_width(2))).map_err(plot_err)?;
            } else {
                chart.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2))).map_err(plot_err)?;
            }
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 2.5, color.filled()))).map_err(plot_err)?;
        }
        line_legend(&legend_strip, curves)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// A short line in each curve's colour and style (dashed or solid) and its name, left to right,
/// wrapping to the next row at the picture's edge.
fn line_legend(area: &DrawingArea<SVGBackend, Shift>, curves: &[Curve]) -> Result<()> {
    let style = TextStyle::from((FONT, 12)).pos(Pos::new(HPos::Left, VPos::Center));
    let (mut x, mut y) = (70, 15);
    for c in curves {
        let width = 36 + 7 * c.name.chars().count() as i32;
        if x > 70 && x + width > SIZE.0 as i32 {
            (x, y) = (70, y + LEGEND_H as i32 - 8);
        }
        let color = COLORS[c.color % COLORS.len()].stroke_width(2);
        if c.dashed {
            for k in 0..3 {
                area.draw(&PathElement::new(vec![(x + 7 * k, y), (x + 7 * k + 4, y)], color)).map_err(plot_err)?;
            }
        } else {
            area.draw(&PathElement::new(vec![(x, y), (x + 18, y)], color)).map_err(plot_err)?;
        }
        area.draw(&Text::new(c.name.clone(), (x + 22, y), style.clone())).map_err(plot_err)?;
        x += width;
    }
    Ok(())
}

/// One dot per grasp: the baseline's error (x) against the tactile network's (y), with the
/// diagonal; dots below it are grasps on which touch helped.
pub fn paired_scatter(title: &str, unit: &str, points: &[(f64, f64)], x_name: &str, y_name: &str) -> Result<String> {
    let top = points.iter().flat_map(|&(a, b)| [a, b]).fold(0.0, f64::max);
    let (max, step) = nice_axis(top * 1.05);
    let (better, worse) = (COLORS[2], COLORS[3]);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..max, 0.0..max)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .light_line_style(TRANSPARENT)
            .x_labels(tick_count(max, step))
            .y_labels(tick_count(max, step))
            .x_label_formatter(&trim)
            .y_label_formatter(&trim)
            .x_desc(format!("{x_name} ({unit})"))
            .y_desc(format!("{y_name} ({unit})"))
            .draw()
            .map_err(plot_err)?;
        chart.draw_series(DashedLineSeries::new([(0.0, 0.0), (max, max)], 4, 3, RGBColor(128, 128, 128).into())).map_err(plot_err)?;
        chart
            .draw_series(points.iter().map(|&(a, b)| Circle::new((a, b), 3.5, (if b < a { better } else { worse }).mix(0.8).filled())))
            .map_err(plot_err)?;
        let below = points.iter().filter(|(a, b)| b < a).count();
        let note = TextStyle::from((FONT, 12)).color(&better).pos(Pos::new(HPos::Left, VPos::Top));
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((0.0, max))
                    + Text::new(format!("below the diagonal (touch better): {below} of {}", points.len()), (10, 6), note),
            ))
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// One figure of a summary (position, angle, ...).
type Metric = fn(&Summary) -> MeanSe;

/// Writes `occlusion-position.svg`, `occlusion-angle.svg`, `objects-position.svg`, for runs that
/// evaluated while training `learning-position.svg` and `learning-angle.svg`, and, per tactile
/// network paired with the vision-only one, `paired-<tactile>-vs-<vision>.svg`.
pub fn write_plots(evals: &[ModelEval], pairs: &[Comparison], out: &Path) -> Result<()> {
    write_breakdowns(evals, out)?;
    write_learning_curves(evals, out)?;
    write_paired(pairs, out)
}

fn write_svg(out: &Path, name: &str, svg: String) -> Result<()> {
    let p = out.join(name);
    std::fs::write(&p, svg).with_context(|| format!("cannot write {}", p.display()))
}

/// The bar charts: errors by occlusion level (and overall), and by object.
fn write_breakdowns(evals: &[ModelEval], out: &Path) -> Result<()> {
    let names: Vec<String> = evals.iter().map(|e| format!("{} ({})", e.name, e.variant.name())).collect();
    let series = |f: Metric, by: &dyn Fn(&ModelEval, Metric) -> Vec<MeanSe>| {
        evals.iter().zip(&names).map(|(e, n)| (n.clone(), by(e, f))).collect::<Vec<_>>()
    };
    // By occlusion bin (and overall).
    let mut groups = vec!["all".to_string()];
    groups.extend(OcclusionBin::ALL.iter().map(|b| b.label().to_string()));
    let bins = |e: &ModelEval, f: Metric| -> Vec<MeanSe> {
        std::iter::once(f(&Summary::of(&e.results)))
            .chain(
                OcclusionBin::ALL
                    .iter()
                    .map(|b| f(&Summary::of(e.results.iter().filter(|r| OcclusionBin::of_f32(r.occlusion) == Some(*b))))),
            )
            .collect()
    };
    write_svg(
        out,
        "occlusion-position.svg",
        bar_chart("Position error by occlusion level", "position error (cm)", &groups, &series(|s| s.position_cm, &bins))?,
    )?;
    write_svg(
        out,
        "occlusion-angle.svg",
        bar_chart("Angle error by occlusion level", "angle error (°)", &groups, &series(|s| s.angle_deg, &bins))?,
    )?;
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
    write_svg(
        out,
        "objects-position.svg",
        bar_chart("Position error by object", "position error (cm)", &objects, &series(|s| s.position_cm, &per_object))?,
    )
}

/// The held-out errors during training, for the runs that evaluated at least twice.
fn write_learning_curves(evals: &[ModelEval], out: &Path) -> Result<()> {
    let with_curve: Vec<(usize, &ModelEval)> = evals.iter().enumerate().filter(|(_, e)| e.curve.len() >= 2).collect();
    if with_curve.is_empty() {
        return Ok(());
    }
    let line = |k: usize, e: &ModelEval, what: &str, dashed: bool, f: fn(&CurvePoint) -> f64| Curve {
        name: format!("{} {what}", e.name),
        color: k,
        dashed,
        points: e.curve.iter().map(|p| (p.epoch as f64, f(p))).collect(),
    };
    let position: Vec<Curve> = with_curve.iter().map(|&(k, e)| line(k, e, "mean", false, |p| p.position_cm)).collect();
    write_svg(
        out,
        "learning-position.svg",
        line_chart("Held-out position error during training", "epoch", "position error (cm)", &position, &[])?,
    )?;
    let angle: Vec<Curve> = with_curve
        .iter()
        .flat_map(|&(k, e)| [line(k, e, "mean", false, |p| p.angle_deg), line(k, e, "median", true, |p| p.angle_median_deg)])
        .collect();
    // A uniformly random rotation's angle error: mean 126.5°, median 132.3° (report/markdown.rs).
    let random = [("uniformly random rotation: median 132°, mean 126°".to_string(), 132.3), (String::new(), 126.5)];
    write_svg(out, "learning-angle.svg", line_chart("Held-out angle error during training", "epoch", "angle error (°)", &angle, &random)?)
}

/// Per tactile network paired with the vision-only one: each grasp's mean position error, one
/// against the other.
fn write_paired(pairs: &[Comparison], out: &Path) -> Result<()> {
    for Comparison { tactile: t, vision: v, paired } in pairs {
        let Some(p) = paired else { continue };
        let pts: Vec<(f64, f64)> = p.grasps.iter().map(|g| (g.vision_position_cm, g.tactile_position_cm)).collect();
        write_svg(
            out,
            &format!("paired-{}-vs-{}.svg", t.name, v.name),
            paired_scatter(
                &format!("Mean position error per grasp: {} vs {}", t.name, v.name),
                "cm",
                &pts,
                &format!("{} (vision only)", v.name),
                &t.name,
            )?,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bars_scale_to_the_data_and_the_svg_is_well_formed() {
        let m = |mean: f64, n: usize| MeanSe { mean, se: 0.1, n };
        let svg = bar_chart(
            "t",
            "cm",
            &["a".into(), "< b".into()],
            &[("x".into(), vec![m(1.0, 10), m(3.0, 11)]), ("y".into(), vec![m(2.0, 12), m(0.5, 13)])],
        )
        .unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Four bars, each with its whisker and sample count; a legend square per series besides.
        let fill = |c: RGBColor| format!(r##"fill="#{:02X}{:02X}{:02X}""##, c.0, c.1, c.2);
        assert_eq!(svg.matches(&fill(COLORS[0])).count(), 2 + 1);
        assert_eq!(svg.matches(&fill(COLORS[1])).count(), 2 + 1);
        for n in 10..14 {
            assert!(svg.contains(&format!(">\n{n}\n</text>")), "count {n}:\n{svg}");
        }
        // Group labels and legend names, escaped.
        for text in ["a", "&lt; b", "x", "y"] {
            assert!(svg.contains(&format!(">\n{text}\n</text>")), "{text}:\n{svg}");
        }
        assert_eq!(nice_axis(3.1 * 1.05), (4.0, 1.0));
        assert_eq!(nice_axis(0.9), (1.0, 0.2));
        let curves = [
            Curve { name: "a mean".into(), color: 0, dashed: false, points: vec![(1.0, 4.0), (2.0, 3.0), (3.0, 2.5)] },
            Curve { name: "a median".into(), color: 0, dashed: true, points: vec![(1.0, 3.5), (2.0, f64::NAN), (3.0, 2.0)] },
        ];
        let lines = line_chart("t", "epoch", "cm", &curves, &[("ref".into(), 5.0)]).unwrap();
        assert!(lines.starts_with("<svg") && lines.trim_end().ends_with("</svg>"));
        // A dot per finite point; both legend entries.
        assert_eq!(lines.matches("<circle").count(), 5);
        for text in ["a mean", "a median", "ref"] {
            assert!(lines.contains(&format!(">\n{text}\n</text>")), "{text}:\n{lines}");
        }
        let sc = paired_scatter("t", "cm", &[(1.0, 0.5), (1.0, 2.0)], "v", "t").unwrap();
        assert!(sc.contains("1 of 2"));
        assert_eq!(sc.matches("<circle").count(), 2);
    }
}
