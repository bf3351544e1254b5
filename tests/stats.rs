//! `vtgen stats`: the plots hold one mark per sample and the page links every plot.

use crate::common::*;

#[test]
fn stats_plots_every_sample_and_the_page_links_them() {
    let ds = reference_dataset();
    let out = tempdir();
    let o = run(&["stats", ds.to_str().unwrap(), "--out", out.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let read = |f: &str| std::fs::read_to_string(out.path().join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
    let samples = 40;
    // Two panels with one dot per sample; the rotation map has two axes per sample plus a legend.
    assert_eq!(read("positions.svg").matches("<circle").count(), 2 * samples);
    assert_eq!(read("rotations.svg").matches("<circle").count(), 2 * samples + 2);
    let occ = read("occlusion.svg");
    assert!(occ.trim_start().starts_with("<svg") && occ.trim_end().ends_with("</svg>"));
    let page = read("stats.md");
    for f in ["positions.svg", "rotations.svg", "occlusion.svg"] {
        assert!(page.contains(&format!("]({f})")), "stats.md links {f}");
    }
    // tiny.yaml has no robot: no touch plots.
    assert!(!out.path().join("contacts.svg").exists());
    // One row per split and bin: every sample is counted once.
    let counts: u64 = ["<80%", "80-85%", ">85%"]
        .iter()
        .flat_map(|b| ["train", "test"].map(|split| format!("| occlusion {b} ({split}) |")))
        .map(|row| {
            let line = page.lines().find(|l| l.starts_with(&row)).unwrap_or_else(|| panic!("no row {row}"));
            line.rsplit('|').nth(1).unwrap().trim().parse::<u64>().unwrap()
        })
        .sum();
    assert_eq!(counts, samples as u64);
}
