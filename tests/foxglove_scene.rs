//! What Foxglove needs for the 3D view: `/scene/models` carries the object and robot meshes as
//! valid glTF, once per shard (and again when the target object changes), in frames that `/tf`
//! gives in every sample.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use foxglove::schemas::{FrameTransforms, SceneUpdate};
use prost::Message;

use crate::common::*;

/// Per sample (log time): topic -> message bytes.
fn messages(shard: &Path) -> BTreeMap<u64, BTreeMap<String, Vec<u8>>> {
    let bytes = std::fs::read(shard).unwrap();
    let mut out: BTreeMap<u64, BTreeMap<String, Vec<u8>>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        out.entry(m.log_time).or_default().insert(m.channel.topic.clone(), m.data.into_owned());
    }
    out
}

/// (min, max) of a GLB's POSITION accessor, after checking the file parses as glTF.
fn glb_bounds(data: &[u8]) -> ([f64; 3], [f64; 3]) {
    let gltf = gltf::Gltf::from_slice(data).expect("valid GLB");
    let prim = gltf.meshes().next().expect("a mesh").primitives().next().expect("a primitive");
    let acc = prim.get(&gltf::Semantic::Positions).expect("positions");
    let v = |j: Option<gltf::json::Value>| -> [f64; 3] {
        let a = j.unwrap();
        [0, 1, 2].map(|k| a[k].as_f64().unwrap())
    };
    assert!(prim.get(&gltf::Semantic::Colors(0)).is_some() && prim.get(&gltf::Semantic::Normals).is_some());
    (v(acc.min()), v(acc.max()))
}

#[test]
fn shards_carry_the_meshes_for_the_3d_view() {
    let dir = crate::grasping::hand_dataset();
    let models: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("models/models_info.json")).unwrap()).unwrap();
    let extents: BTreeMap<String, Vec<f64>> = models["objects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| (o["id"].as_str().unwrap().to_string(), o["extents"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()))
        .collect();
    let shards = complete_shards(dir);
    assert!(!shards.is_empty());
    for shard in &shards {
        let samples = messages(&dir.join(shard));
        let mut current: Option<(String, BTreeSet<String>)> = None;
        for (t, topics) in &samples {
            let info: serde_json::Value = serde_json::from_slice(&topics["/sample/info"]).unwrap();
            let object = info["object_id"].as_str().unwrap().to_string();
            if let Some(raw) = topics.get("/scene/models") {
                let update = SceneUpdate::decode(&raw[..]).unwrap();
                let mut frames = BTreeSet::new();
                let mut shown = None;
                for e in &update.entities {
                    assert!(e.frame_locked, "{shard}: entity {} must follow its frame", e.id);
                    assert_eq!(e.models.len(), 1);
                    let m = &e.models[0];
                    assert_eq!(m.media_type, "model/gltf-binary");
                    let (lo, hi) = glb_bounds(&m.data);
                    frames.insert(e.frame_id.clone());
                    if let Some(id) = e.id.strip_prefix("object/") {
                        assert_eq!(e.frame_id, "object");
                        // The model frame is the bounding-box centre: the glTF bounds are ± extents / 2.
                        for k in 0..3 {
                            assert!((hi[k] - lo[k] - extents[id][k]).abs() < 1e-4 && (hi[k] + lo[k]).abs() < 1e-4, "{id}: {lo:?} {hi:?}");
                        }
                        shown = Some(id.to_string());
                    }
                }
                assert!(update.entities.iter().filter(|e| e.id.starts_with("robot/")).count() >= 20, "arm and hand links");
                current = Some((shown.expect("the target object is shown"), frames));
            }
            let (shown, frames) = current.as_ref().unwrap_or_else(|| panic!("{shard}: first sample has no /scene/models"));
            assert_eq!(*shown, object, "{shard} @ {t}: the scene shows the target object");
            let tf = FrameTransforms::decode(&topics["/tf"][..]).unwrap();
            let have: BTreeSet<&str> = tf.transforms.iter().map(|f| f.child_frame_id.as_str()).collect();
            for f in frames {
                assert!(have.contains(f.as_str()), "{shard} @ {t}: /tf lacks frame {f}");
            }
        }
    }
}
