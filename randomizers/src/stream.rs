//! Counter-based random streams. Every random choice of a sample derives only from
//! (config seed, object id, trajectory, instance), so any shard can be generated alone, on any
//! machine, in any order, and produce the same bytes.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sha2::{Digest, Sha256};

/// The coordinates of one sample in the dataset's random space.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SampleKey<'a> {
    pub seed: u64,
    pub object_id: &'a str,
    pub trajectory: u32,
    pub instance: u32,
}

/// A ChaCha8 stream keyed by SHA-256 of the sample key and a purpose label, so that independent
/// concerns (pose, appearance, later physics) never share or shift each other's numbers.
pub struct SampleStream;

impl SampleStream {
    /// The stream of one trajectory (shared by all its instances), for `purpose`.
    pub fn trajectory(seed: u64, object_id: &str, trajectory: u32, purpose: &str) -> ChaCha8Rng {
        ChaCha8Rng::from_seed(key(&[
            b"trajectory",
            purpose.as_bytes(),
            &seed.to_le_bytes(),
            object_id.as_bytes(),
            &trajectory.to_le_bytes(),
        ]))
    }

    /// The stream of one sample, for `purpose`.
    pub fn sample(k: &SampleKey, purpose: &str) -> ChaCha8Rng {
        ChaCha8Rng::from_seed(key(&[
            b"sample",
            purpose.as_bytes(),
            &k.seed.to_le_bytes(),
            k.object_id.as_bytes(),
            &k.trajectory.to_le_bytes(),
            &k.instance.to_le_bytes(),
        ]))
    }
}

fn key(parts: &[&[u8]]) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(b"vtgen-stream-v1");
    for p in parts {
        // Length-prefixed so that ("ab", "c") and ("a", "bc") differ.
        h.update((p.len() as u64).to_le_bytes());
        h.update(p);
    }
    h.finalize().into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn streams_depend_on_every_key_part_and_nothing_else() {
        let k = SampleKey { seed: 1, object_id: "a", trajectory: 2, instance: 3 };
        let x: u64 = SampleStream::sample(&k, "pose").random();
        assert_eq!(x, SampleStream::sample(&k, "pose").random::<u64>());
        for other in [
            SampleKey { seed: 2, ..k },
            SampleKey { object_id: "b", ..k },
            SampleKey { trajectory: 3, ..k },
            SampleKey { instance: 4, ..k },
        ] {
            assert_ne!(x, SampleStream::sample(&other, "pose").random::<u64>());
        }
        assert_ne!(x, SampleStream::sample(&k, "appearance").random::<u64>());
    }
}
