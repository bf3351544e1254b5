//! The episode picture strip of the docs: one episode of a dataset made with `sampling.record`,
//! as evenly spaced camera frames (cropped around the object), under each the optical image of the
//! fingertip that touches most at that instant, and along the bottom the object's speed at every
//! state (physics step) with the frames marked.
//!
//! ```text
//! cargo run --release -p vtgen --example episode_strip -- DATASET OUT.png [--frames N] [--shard K]
//! ```

use anyhow::{Context, Result, bail};
use image::{Rgb, RgbImage};
use vt_dataset::{DatasetReader, Sample};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).map(|v| v.parse::<usize>());
    let (Some(dataset), Some(out)) = (args.first(), args.get(1)) else {
        bail!("usage: episode_strip DATASET OUT.png [--frames N] [--shard K]")
    };
    let n = flag("--frames").unwrap_or(Ok(6)).context("--frames")?;
    let k = flag("--shard").unwrap_or(Ok(0)).context("--shard")?;
    let ds = DatasetReader::open(std::path::Path::new(dataset))?;
    let shards = ds.shards("train")?;
    let shard = shards.get(k).context("no such train shard")?;
    let indices: Vec<u64> = shard.indices().collect();
    let frames: Vec<Sample> = indices.iter().map(|&i| shard.read(i)).collect::<Result<_>>()?;
    if frames.first().and_then(|s| s.episode.as_ref()).is_none() {
        bail!("{dataset} is not an episode dataset (sampling.record)");
    }
    let picks: Vec<&Sample> = (0..n).map(|j| &frames[j * (frames.len() - 1) / (n - 1).max(1)]).collect();
    let (cw, ch) = (240u32, 180u32);
    let tile_h = ch + ch;
    let plot_h = 90u32;
    let mut strip = RgbImage::from_pixel(n as u32 * (cw + 4), tile_h + plot_h + 8, Rgb([255, 255, 255]));
    // One crop box for the whole episode: the union of the object's mask over the picked frames.
    let (w, h) = (picks[0].width, picks[0].height);
    let (mut u0, mut v0, mut u1, mut v1) = (w, h, 0, 0);
    for s in &picks {
        for (i, m) in s.mask.iter().enumerate() {
            if *m == vt_dataset::mask_ids::TARGET_OBJECT {
                let (u, v) = (i as u32 % w, i as u32 / w);
                (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
            }
        }
    }
    let half = (((u1.saturating_sub(u0)) as f64).max(v1.saturating_sub(v0) as f64 * 4.0 / 3.0) * 0.9).clamp(60.0, w as f64 / 2.0);
    let (cu, cv) = ((u0 + u1) as f64 / 2.0, (v0 + v1) as f64 / 2.0);
    let x0 = (cu - half).clamp(0.0, w as f64 - 2.0 * half) as u32;
    let y0 = (cv - half * 0.75).clamp(0.0, (h as f64 - 1.5 * half).max(0.0)) as u32;
    for (j, s) in picks.iter().enumerate() {
        let rgb = RgbImage::from_raw(w, h, s.rgb.clone()).context("rgb size")?;
        let crop = image::imageops::crop_imm(&rgb, x0, y0, (2.0 * half) as u32, (1.5 * half) as u32).to_image();
        let crop = image::imageops::resize(&crop, cw, ch, image::imageops::FilterType::Triangle);
        let x = j as u32 * (cw + 4);
        image::imageops::overlay(&mut strip, &crop, x as i64, 0);
        // The fingertip whose image is furthest from its reference: the firmest touch.
        let touch = s.tactile.as_ref().and_then(|t| {
            t.optical.iter().max_by_key(|o| o.image.iter().zip(&o.reference).map(|(a, b)| a.abs_diff(*b) as u64).sum::<u64>())
        });
        if let Some(o) = touch {
            let img = RgbImage::from_raw(o.width, o.height, o.image.clone()).context("optical image size")?;
            image::imageops::overlay(
                &mut strip,
                &image::imageops::resize(&img, cw, ch, image::imageops::FilterType::Triangle),
                x as i64,
                ch as i64,
            );
        }
    }
    // The object's speed over the episode, every state; the picked frames as grey ticks.
    let states: Vec<(f64, f64)> = frames
        .iter()
        .flat_map(|s| {
            s.episode.iter().flat_map(|e| e.states.iter().map(|(_, st)| (st.time_s, glam::DVec3::from(st.linear_velocity).length())))
        })
        .collect();
    let t_end = states.last().map_or(1.0, |s| s.0).max(1e-9);
    let v_max = states.iter().map(|s| s.1).fold(1e-9, f64::max);
    let (pw, top) = (strip.width() - 1, tile_h + 6);
    let at = |t: f64, v: f64| ((t / t_end * pw as f64) as u32, top + plot_h - 1 - (v / v_max * (plot_h - 2) as f64) as u32);
    for s in &picks {
        let t = s.info.episode.map_or(0.0, |e| e.time_s);
        let (x, _) = at(t, 0.0);
        for y in top..top + plot_h {
            strip.put_pixel(x.min(pw), y, Rgb([200, 200, 200]));
        }
    }
    for pair in states.windows(2) {
        let (a, b) = (at(pair[0].0, pair[0].1), at(pair[1].0, pair[1].1));
        for y in a.1.min(b.1)..=a.1.max(b.1) {
            strip.put_pixel(b.0.min(pw), y, Rgb([40, 90, 200]));
        }
    }
    strip.save(out).with_context(|| format!("cannot write {out}"))?;
    println!("{out}: {n} of {} frames of {}, {:.2} s; object speed peak {:.3} m/s", frames.len(), shard.path().display(), t_end, v_max);
    Ok(())
}
