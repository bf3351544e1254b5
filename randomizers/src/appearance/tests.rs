use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

use super::*;
use crate::config::CameraJitter;
use crate::images::tests::write_image;

const CENTER: DVec3 = DVec3::new(0.02, -0.01, 0.25);

fn ctx(images: &ImageLibrary) -> AppearanceContext<'_> {
    AppearanceContext { workspace_center: CENTER, workspace_half_extent: [0.3, 0.2], distractor_candidates: 5, images }
}

fn key(object_id: &str, trajectory: u32, instance: u32) -> SampleKey<'_> {
    SampleKey { seed: 7, object_id, trajectory, instance }
}

/// Randomization on, with distractors and camera jitter.
fn full_config() -> RandomizationConfig {
    RandomizationConfig {
        enabled: true,
        distractors: [1, 4],
        camera_jitter: CameraJitter { translation_m: 0.02, rotation_deg: 3.0 },
        ..Default::default()
    }
}

/// A library of two one-colour PNGs in a temp folder, and the config using it for the backdrop.
fn with_images() -> (tempfile::TempDir, ImageLibrary, RandomizationConfig) {
    let dir = tempfile::tempdir().unwrap();
    write_image(dir.path(), "red.png", 32, 16, [220, 30, 30]);
    write_image(dir.path(), "blue.png", 16, 32, [30, 30, 220]);
    let mut cfg = full_config();
    cfg.backdrop.kinds.push(TextureKind::Image);
    cfg.backdrop.image_dir = Some(dir.path().to_path_buf());
    let lib = ImageLibrary::for_config(&cfg, Path::new("/")).unwrap();
    assert_eq!(lib.len(), 2);
    (dir, lib, cfg)
}

#[test]
fn same_key_same_bytes_different_keys_differ() {
    let (_dir, lib, cfg) = with_images();
    let ctx = ctx(&lib);
    let mut seen: Vec<Appearance> = Vec::new();
    for i in 0..12 {
        let k = key("005_tomato_soup_can", 3, i);
        let a = sample_appearance(&cfg, &k, &ctx);
        let b = sample_appearance(&cfg, &k, &ctx);
        assert_eq!(a, b);
        assert_eq!(a.floor.rgba, b.floor.rgba);
        assert_eq!(a.info(), sample_appearance_info(&cfg, &k, &ctx));
        // The metadata survives JSON.
        let json = serde_json::to_string(&a.info()).unwrap();
        assert_eq!(serde_json::from_str::<AppearanceInfo>(&json).unwrap(), a.info());
        if a.randomized {
            for s in seen.iter().filter(|s| s.randomized) {
                assert_ne!(s.light, a.light);
                assert_ne!(s.floor, a.floor);
                assert_ne!(s.backdrop_pattern, a.backdrop_pattern);
            }
        } else {
            let mut c = Appearance::canonical();
            c.light.target = CENTER;
            assert_eq!(a, c);
        }
        seen.push(a);
    }
    assert!(seen.iter().any(|a| a.randomized) && seen.iter().any(|a| !a.randomized));
    // Other seed and other object: other appearance.
    let k = key("005_tomato_soup_can", 3, 1);
    let a = sample_appearance_info(&cfg, &k, &ctx);
    assert!(a.randomized);
    for other in [SampleKey { seed: 8, ..k }, SampleKey { object_id: "x", ..k }, SampleKey { trajectory: 4, ..k }] {
        let b = sample_appearance_info(&cfg, &other, &ctx);
        assert_ne!(a.light.position, b.light.position);
    }
}

#[test]
fn a_new_parameter_range_shifts_no_other_parameter() {
    let lib = ImageLibrary::empty();
    let base = full_config();
    let mut changed = base.clone();
    changed.light.intensity = [2.0, 3.0];
    changed.distractors = [0, 9];
    for i in 0..20 {
        let k = key("a", 0, i);
        let (a, b) = (sample_appearance_info(&base, &k, &ctx(&lib)), sample_appearance_info(&changed, &k, &ctx(&lib)));
        if a.randomized {
            assert_eq!((a.light.position, a.light.color, a.light.cone_deg), (b.light.position, b.light.color, b.light.cone_deg));
            assert_eq!((&a.floor, &a.backdrop, a.ambient, a.camera_rotation), (&b.floor, &b.backdrop, b.ambient, b.camera_rotation));
            assert_ne!(a.light.intensity, b.light.intensity);
        }
    }
}

/// Unrandomized flags of object `obj` in dataset order, `n` instances per trajectory; with `test`
/// only the test split of a 4:1 split (trajectories t mod 5 == 4).
fn flags(cfg: &RandomizationConfig, obj: &str, n: u32, total: usize, test: bool) -> Vec<bool> {
    (0u32..)
        .filter(|t| !test || t % 5 == 4)
        .flat_map(|t| (0..n).map(move |i| (t, i)))
        .take(total)
        .map(|(t, i)| is_unrandomized(cfg, &key(obj, t, i)))
        .collect()
}

#[test]
fn unrandomized_share_holds_within_one_percent_in_every_window_of_1000() {
    let mut worst: f64 = 0.0;
    for share in [0.2, 0.5, 0.05, 0.37, 0.9] {
        let cfg = RandomizationConfig { enabled: true, unrandomized_share: share, ..Default::default() };
        for (obj, test) in [("003_cracker_box", false), ("035_power_drill", false), ("003_cracker_box", true)] {
            for n in [100, 10, 2, 1, 7, 33] {
                let f = flags(&cfg, obj, n, 3000, test);
                let mut prefix = vec![0usize];
                for &u in &f {
                    prefix.push(prefix.last().unwrap() + u as usize);
                }
                for start in 0..=f.len() - 1000 {
                    let got = (prefix[start + 1000] - prefix[start]) as f64 / 1000.0;
                    worst = worst.max((got - share).abs());
                    assert!(
                        (got - share).abs() <= 0.01,
                        "share {share}, {obj}, test split {test}, {n} instances/trajectory, window at {start}: {got}"
                    );
                }
            }
        }
    }
    eprintln!("largest deviation of the unrandomized share over 1000 samples: {worst:.4}");
}

#[test]
fn share_zero_none_share_one_all_disabled_all_canonical() {
    let lib = ImageLibrary::empty();
    let none = RandomizationConfig { enabled: true, unrandomized_share: 0.0, ..Default::default() };
    let all = RandomizationConfig { enabled: true, unrandomized_share: 1.0, ..Default::default() };
    let off = RandomizationConfig { enabled: false, unrandomized_share: 0.0, ..Default::default() };
    for n in [1, 100] {
        assert!(flags(&none, "a", n, 1000, false).iter().all(|&u| !u));
        assert!(flags(&all, "a", n, 1000, false).iter().all(|&u| u));
        assert!(flags(&off, "a", n, 1000, false).iter().all(|&u| u));
    }
    let mut canonical = Appearance::canonical();
    canonical.light.target = CENTER;
    for i in 0..5 {
        assert_eq!(sample_appearance(&off, &key("a", 1, i), &ctx(&lib)), canonical);
        assert!(sample_appearance(&none, &key("a", 1, i), &ctx(&lib)).randomized);
    }
}

#[test]
fn canonical_appearance() {
    let c = Appearance::canonical();
    assert!(!c.randomized);
    assert_eq!(c.light.position, DVec3::new(0.4, -0.6, 1.4));
    assert_eq!((c.light.intensity, c.light.cone_deg, c.light.softness), (1.0, 45.0, 0.8));
    assert_eq!(c.floor, checker_texture_canonical());
    assert_eq!(c.floor_tile, 0.4);
    assert_eq!((c.camera_offset, c.distractors.len()), ((DVec3::ZERO, DVec3::ZERO), 0));
    assert_eq!((c.backdrop.width, c.backdrop.height), (256, 256));
    // Light grey with a subtle grain.
    let lum: Vec<u8> = c.backdrop.rgba.chunks_exact(4).map(|p| p[1]).collect();
    let (lo, hi) = (*lum.iter().min().unwrap(), *lum.iter().max().unwrap());
    assert!(lo >= 190 && hi <= 205 && hi > lo, "{lo}..{hi}");
    assert_eq!(c.info(), AppearanceInfo::canonical());
}

fn checker_texture_canonical() -> ProceduralTexture {
    crate::checker_texture(256, 8, [150, 150, 145], [110, 110, 108])
}

/// (min, max) of `values`, asserting each lies within [lo, hi] and both ends come within 5% of
/// the range of lo and hi.
fn covers(name: &str, values: impl IntoIterator<Item = f64>, lo: f64, hi: f64) {
    let v: Vec<f64> = values.into_iter().collect();
    assert!(v.len() >= 500, "{name}: only {} values", v.len());
    let (min, max) = v.iter().fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    let tol = 0.05 * (hi - lo);
    let eps = 1e-9 * (1.0 + hi.abs().max(lo.abs()));
    assert!(min >= lo - eps && max <= hi + eps, "{name}: [{min}, {max}] leaves [{lo}, {hi}]");
    assert!(min <= lo + tol && max >= hi - tol, "{name}: [{min}, {max}] does not cover [{lo}, {hi}]");
}

/// Vectors drawn in a ball of `radius`: none outside, the largest within 5% of the radius, and
/// every axis reaching at least half the radius in both directions.
fn in_ball(name: &str, v: impl IntoIterator<Item = DVec3>, radius: f64) {
    let v: Vec<DVec3> = v.into_iter().collect();
    let max = v.iter().map(|p| p.length()).fold(0.0, f64::max);
    assert!(max <= radius * (1.0 + 1e-9) && max >= 0.95 * radius, "{name}: largest {max} for radius {radius}");
    for i in 0..3 {
        let (lo, hi) = v.iter().fold((0f64, 0f64), |(lo, hi), p| (lo.min(p[i]), hi.max(p[i])));
        assert!(lo <= -0.5 * radius && hi >= 0.5 * radius, "{name}[{i}]: [{lo}, {hi}] for radius {radius}");
    }
}

/// Hue in [0, 1) of an RGB colour (0 for greys).
fn hue(c: [f32; 3]) -> f32 {
    let (max, min) = (c[0].max(c[1]).max(c[2]), c[0].min(c[1]).min(c[2]));
    let d = max - min;
    if d <= 1e-6 {
        return 0.0;
    }
    let h = if max == c[0] {
        ((c[1] - c[2]) / d).rem_euclid(6.0)
    } else if max == c[1] {
        (c[2] - c[0]) / d + 2.0
    } else {
        (c[0] - c[1]) / d + 4.0
    };
    h / 6.0
}

// Long on purpose: one loop over 1000 scenes, then one range check per randomized parameter.
#[test]
fn over_1000_scenes_every_parameter_covers_its_range() {
    let (_dir, lib, cfg) = with_images();
    let ctx = ctx(&lib);
    let n = 1000;
    let samples: Vec<AppearanceInfo> = (0..n).map(|s| sample_appearance_info(&cfg, &key("obj", s / 100, s % 100), &ctx)).collect();
    let r: Vec<&AppearanceInfo> = samples.iter().filter(|a| a.randomized).collect();
    let canonical = samples.iter().filter(|a| !a.randomized).count();
    assert!((canonical as f64 / n as f64 - 0.2).abs() <= 0.01, "{canonical}");
    for a in samples.iter().filter(|a| !a.randomized) {
        let mut c = AppearanceInfo::canonical();
        c.light.target = CENTER;
        assert_eq!(*a, c);
    }

    let l = &cfg.light;
    for i in 0..3 {
        covers(&format!("light.position[{i}]"), r.iter().map(|a| a.light.position[i]), l.position_min[i], l.position_max[i]);
    }
    in_ball("light target - workspace centre", r.iter().map(|a| a.light.target - CENTER), l.target_radius_m);
    covers("light.intensity", r.iter().map(|a| a.light.intensity as f64), 0.6, 1.6);
    covers("light.cone_deg", r.iter().map(|a| a.light.cone_deg), 25.0, 50.0);
    covers("light.softness", r.iter().map(|a| a.light.softness), 0.6, 0.9);
    covers("ambient level", r.iter().map(|a| a.ambient.iter().fold(0f32, |m, &v| m.max(v)) as f64), 0.05, 0.45);
    covers("floor_tile", r.iter().map(|a| a.floor_tile), 0.2, 1.0);
    covers("backdrop_tile", r.iter().map(|a| a.backdrop_tile), 0.2, 1.0);

    // Light colour: max component 1, temperature from warm to cool, and every hue sector present.
    for a in &r {
        let m = a.light.color.iter().fold(0f32, |m, &v| m.max(v));
        assert!((m - 1.0).abs() < 1e-6 && a.light.color.iter().all(|&v| v >= 0.0), "{:?}", a.light.color);
    }
    let blue_red: Vec<f64> = r.iter().map(|a| (a.light.color[2] / a.light.color[0].max(1e-3)) as f64).collect();
    let (br_min, br_max) = blue_red.iter().fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    let (warm, cool) = (blackbody_rgb(2700.0), blackbody_rgb(9000.0));
    assert!(br_min < 1.1 * (warm[2] / warm[0]) as f64 && br_max > 0.9 * (cool[2] / cool[0]) as f64, "blue/red {br_min}..{br_max}");
    let mut sectors = [0usize; 6];
    for a in &r {
        sectors[((hue(a.light.color) * 6.0) as usize).min(5)] += 1;
    }
    // Chromaticity spread: r/(r+g+b) and g/(r+g+b) vary.
    let chroma: Vec<[f64; 2]> = r
        .iter()
        .map(|a| {
            let s = a.light.color.iter().sum::<f32>() as f64;
            [a.light.color[0] as f64 / s, a.light.color[1] as f64 / s]
        })
        .collect();
    let sd = |i: usize| {
        let m = chroma.iter().map(|c| c[i]).sum::<f64>() / chroma.len() as f64;
        (chroma.iter().map(|c| (c[i] - m).powi(2)).sum::<f64>() / chroma.len() as f64).sqrt()
    };
    eprintln!("light hue sectors (R, Y, G, C, B, M): {sectors:?}; chromaticity sd r {:.3} g {:.3}", sd(0), sd(1));
    assert!(sectors.iter().all(|&s| s >= 16), "every hue sector (2%): {sectors:?}");
    assert!(sd(0) > 0.04 && sd(1) > 0.015, "chromaticity spread r {} g {}", sd(0), sd(1));

    // Texture kinds: all occur, roughly equally (6 backdrop kinds incl. image, 5 floor kinds).
    for (surface, pattern, kinds) in [
        ("floor", r.iter().map(|a| &a.floor).collect::<Vec<_>>(), 5.0),
        ("backdrop", r.iter().map(|a| &a.backdrop).collect::<Vec<_>>(), 6.0),
    ] {
        let mut count: BTreeMap<TextureKind, usize> = BTreeMap::new();
        for p in &pattern {
            *count.entry(p.kind().expect("a random kind")).or_default() += 1;
        }
        let expected = r.len() as f64 / kinds;
        eprintln!("{surface} kinds: {count:?}");
        assert_eq!(count.len(), kinds as usize, "{surface}: {count:?}");
        for (k, &c) in &count {
            assert!((c as f64 - expected).abs() < 0.3 * expected, "{surface} {k:?}: {c} of {}", r.len());
        }
    }
    let images: BTreeMap<String, usize> = r.iter().fold(BTreeMap::new(), |mut m, a| {
        if let TextureSpec::Image { name, .. } = &a.backdrop {
            *m.entry(name.clone()).or_default() += 1;
        }
        m
    });
    assert_eq!(images.keys().collect::<Vec<_>>(), ["blue.png", "red.png"]);

    // Distractors: counts over [1, 4], candidates over all 5, positions over the extents, yaw over a turn.
    let counts: Vec<f64> = r.iter().map(|a| a.distractors.len() as f64).collect();
    covers("distractor count", counts.iter().copied(), 1.0, 4.0);
    for c in 1..=4 {
        assert!(counts.iter().filter(|&&x| x == c as f64).count() > r.len() / 8, "count {c}");
    }
    let all: Vec<&Distractor> = r.iter().flat_map(|a| &a.distractors).collect();
    covers("distractor candidate", all.iter().map(|d| d.candidate as f64), 0.0, 4.0);
    covers("distractor x", all.iter().map(|d| d.position_xy[0]), CENTER.x - 0.3, CENTER.x + 0.3);
    covers("distractor y", all.iter().map(|d| d.position_xy[1]), CENTER.y - 0.2, CENTER.y + 0.2);
    covers("distractor yaw", all.iter().map(|d| d.yaw), 0.0, TAU);

    // Camera jitter: within the limits and reaching near them, in every direction.
    in_ball("camera translation", r.iter().map(|a| a.camera_translation), 0.02);
    in_ball("camera rotation (deg)", r.iter().map(|a| a.camera_rotation * 180.0 / PI), 3.0);
    // The rotation angle is uniform in [0, max]: small angles occur too.
    covers("camera rotation angle", r.iter().map(|a| a.camera_rotation.length().to_degrees()), 0.0, 3.0);
}

#[test]
fn sampled_scenes_render_and_image_textures_come_from_the_library() {
    let (_dir, lib, mut cfg) = with_images();
    cfg.backdrop.kinds = vec![TextureKind::Image];
    cfg.texture_size = 64;
    let ctx = ctx(&lib);
    let mut names = BTreeMap::new();
    for i in 0..40 {
        let a = sample_appearance(&cfg, &key("img", 0, i), &ctx);
        if !a.randomized {
            continue;
        }
        assert_eq!((a.floor.width, a.floor.height), (64, 64));
        let TextureSpec::Image { group, index, name } = &a.backdrop_pattern else { panic!("{:?}", a.backdrop_pattern) };
        assert_eq!(&a.backdrop, lib.image(*group, *index).unwrap());
        let centre = a.backdrop.pixel(128, 128);
        let expect = if name == "red.png" { [220, 30, 30, 255] } else { [30, 30, 220, 255] };
        assert_eq!(centre, expect);
        *names.entry(name.clone()).or_insert(0) += 1;
    }
    assert_eq!(names.len(), 2, "{names:?}");
    // Without images for the surface, the image kind is left out (here: the only kind, so canonical).
    let empty = ImageLibrary::empty();
    let a = sample_appearance_info(&cfg, &key("img", 0, 1), &AppearanceContext { images: &empty, ..ctx });
    assert!(a.randomized);
    assert_eq!(a.backdrop, AppearanceInfo::canonical().backdrop);
}

#[test]
fn no_candidates_no_distractors_and_zero_jitter_is_exactly_zero() {
    let lib = ImageLibrary::empty();
    let cfg = RandomizationConfig { enabled: true, unrandomized_share: 0.0, distractors: [2, 3], ..Default::default() };
    let none = AppearanceContext { distractor_candidates: 0, ..ctx(&lib) };
    for i in 0..20 {
        let a = sample_appearance_info(&cfg, &key("a", 0, i), &none);
        assert!(a.distractors.is_empty());
        assert_eq!((a.camera_translation, a.camera_rotation), (DVec3::ZERO, DVec3::ZERO));
        assert!(a.light.direction().length() > 0.99);
        assert!((a.light.inner_cone_deg() - a.light.softness * a.light.cone_deg).abs() < 1e-12);
    }
}

/// Texture timings: `cargo test -p vt-randomizers --release -- --ignored --nocapture timings`.
#[test]
#[ignore]
fn timings() {
    use std::time::Instant;
    let lib = ImageLibrary::empty();
    for kind in TextureKind::PROCEDURAL {
        let specs: Vec<TextureSpec> = (0..50u64)
            .map(|s| crate::texture::random_spec(&mut <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(s), kind, &lib, None))
            .collect();
        let t = Instant::now();
        for s in &specs {
            std::hint::black_box(s.render(256, &lib));
        }
        eprintln!("{:>8}: {:.3} ms per 256² texture", kind.name(), t.elapsed().as_secs_f64() * 1e3 / specs.len() as f64);
    }
    let cfg = full_config();
    let t = Instant::now();
    for i in 0..200 {
        std::hint::black_box(sample_appearance(&cfg, &key("a", i / 100, i % 100), &ctx(&lib)));
    }
    eprintln!("sample_appearance: {:.3} ms per sample", t.elapsed().as_secs_f64() * 1e3 / 200.0);
    let t = Instant::now();
    for i in 0..1000 {
        std::hint::black_box(sample_appearance_info(&cfg, &key("a", i / 100, i % 100), &ctx(&lib)));
    }
    eprintln!("sample_appearance_info: {:.4} ms per sample", t.elapsed().as_secs_f64() * 1e3 / 1000.0);
}
