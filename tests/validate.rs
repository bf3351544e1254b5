//! `vtgen validate` passes a clean dataset and names what is wrong with a broken one: a truncated
//! shard, a flipped byte inside a chunk, a shard missing from the manifest, a sample missing a
//! message.

use std::path::Path;

use crate::common::*;

fn copy_dataset() -> tempfile::TempDir {
    let d = tempdir();
    for (rel, bytes) in files(reference_dataset()) {
        let p = d.path().join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    d
}

fn validate(dir: &Path) -> (bool, String) {
    let o = run(&["validate", dir.to_str().unwrap(), "--full"]);
    (o.status.success(), format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o)))
}

#[test]
fn a_clean_dataset_is_valid() {
    let (ok, out) = validate(reference_dataset());
    assert!(ok, "{out}");
    assert!(out.contains("5 shards, 40 samples read, ground truth checked on 40: valid"), "{out}");
}

#[test]
fn a_truncated_shard_is_named() {
    let d = copy_dataset();
    let f = d.path().join("train/shard-00001.mcap");
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() / 2]).unwrap();
    let (ok, out) = validate(d.path());
    assert!(!ok);
    assert!(out.contains("train/shard-00001.mcap") && out.contains("truncated"), "{out}");
}

#[test]
fn a_flipped_byte_inside_a_chunk_is_named_with_its_sample() {
    let d = copy_dataset();
    let f = d.path().join("train/shard-00002.mcap");
    let mut bytes = std::fs::read(&f).unwrap();
    // The middle of the file is inside a sample's compressed chunk.
    let i = bytes.len() / 2;
    bytes[i] ^= 0x40;
    std::fs::write(&f, &bytes).unwrap();
    let (ok, out) = validate(d.path());
    assert!(!ok);
    assert!(out.contains("train/shard-00002.mcap: SHA-256 differs"), "{out}");
    assert!(out.contains("train/shard-00002.mcap sample "), "the damaged sample is named: {out}");
}

#[test]
fn a_damaged_chunk_size_is_an_error_not_an_abort() {
    let d = copy_dataset();
    let f = d.path().join("train/shard-00001.mcap");
    let mut bytes = std::fs::read(&f).unwrap();
    // Walk the records after the 8-byte magic (opcode, u64 length, content) to the first chunk
    // record (opcode 0x06); its uncompressed size sits 25 bytes in.
    let mut chunk = 8;
    while bytes[chunk] != 0x06 {
        chunk += 9 + u64::from_le_bytes(bytes[chunk + 1..chunk + 9].try_into().unwrap()) as usize;
    }
    bytes[chunk + 25..chunk + 33].copy_from_slice(&0x2A2A_2A2A_2A2A_2A2Au64.to_le_bytes());
    std::fs::write(&f, &bytes).unwrap();
    let o = run(&["validate", d.path().to_str().unwrap(), "--full"]);
    assert_eq!(o.status.code(), Some(1), "exits with an error, not a signal: {}", stderr(&o));
    let out = format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    assert!(out.contains("train/shard-00001.mcap sample ") && out.contains("the chunk header is damaged"), "{out}");
}

#[test]
fn a_shard_missing_from_the_manifest_is_named() {
    let d = copy_dataset();
    let path = d.path().join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let shards = m["splits"]["train"]["shards"].as_array_mut().unwrap();
    shards.retain(|s| s["file"] != "train/shard-00003.mcap");
    std::fs::write(&path, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    let (ok, out) = validate(d.path());
    assert!(!ok);
    assert!(out.contains("train/shard-00003.mcap: complete shard on disk but not in the manifest"), "{out}");
}

#[test]
fn a_sample_missing_a_message_is_named() {
    let d = copy_dataset();
    let file = "test/shard-00000.mcap";
    let path = d.path().join(file);
    let original = std::fs::read(&path).unwrap();
    // Re-mux the shard without sample 2's mask: one chunk per sample, metadata kept.
    let summary = mcap::Summary::read(&original).unwrap().unwrap();
    let meta_index = summary.metadata_indexes.iter().find(|m| m.name == "vtgen.shard").unwrap();
    let meta = mcap::read::metadata(&original, meta_index).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new().chunk_size(None).create(&mut out).unwrap();
        let mut last = None;
        for msg in mcap::MessageStream::new(&original).unwrap() {
            let msg = msg.unwrap();
            if last.is_some_and(|t| t != msg.log_time) {
                w.flush().unwrap();
            }
            last = Some(msg.log_time);
            if msg.log_time == 2 * vt_dataset::SAMPLE_PERIOD_NS && msg.channel.topic == "/camera/mask" {
                continue;
            }
            w.write(&msg).unwrap();
        }
        w.flush().unwrap();
        w.write_metadata(&meta).unwrap();
        w.finish().unwrap();
    }
    std::fs::write(&path, out.into_inner()).unwrap();
    // The manifest is updated to the new file, so only the missing message is wrong.
    let mpath = d.path().join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    let (bytes, sha) = vt_dataset::sha256_file(&path).unwrap();
    m["splits"]["test"]["shards"][0]["bytes"] = bytes.into();
    m["splits"]["test"]["shards"][0]["sha256"] = sha.into();
    std::fs::write(&mpath, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    let (ok, out) = validate(d.path());
    assert!(!ok);
    assert!(out.contains("test/shard-00000.mcap sample 2: missing message on /camera/mask"), "{out}");
    assert_eq!(out.matches("problem:").count(), 1, "{out}");
}

#[test]
fn preview_writes_a_contact_sheet() {
    let d = tempdir();
    let out = d.path().join("sheet.png");
    let o = run(&["preview", reference_dataset().to_str().unwrap(), "--n", "3", "--out", out.to_str().unwrap(), "--width", "400"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!(img.width(), 400);
    assert!(img.height() >= 3 * 100, "three rows");
}
