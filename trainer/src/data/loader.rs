//! The background loader: batches prepared on their own thread, over a bounded channel.

use super::*;

/// One pass over (some of) a split: its epoch number (seeds the sampling) and the order.
#[derive(Debug, Clone)]
pub struct Pass {
    pub epoch: u64,
    pub order: Vec<usize>,
}

/// A message of the loader: a batch of `epoch`, or the pass's end with the samples it skipped
/// (not visible: no object pixel with depth).
#[derive(Debug)]
pub enum Loaded {
    Batch { epoch: u64, batch: Batch },
    EndOfPass { epoch: u64, skipped: Vec<u64> },
}

/// Prepares batches on a background thread, `prefetch` ahead, over a bounded channel.
pub struct Loader {
    rx: Option<Receiver<Result<Loaded>>>,
    handle: Option<JoinHandle<SplitSource>>,
}

impl Loader {
    /// Starts the thread; it owns `source` until [`Loader::finish`] hands it back.
    pub fn spawn(mut source: SplitSource, passes: Vec<Pass>, opts: PrepareOptions, batch_size: usize, prefetch: usize) -> Loader {
        let (tx, rx) = sync_channel::<Result<Loaded>>(prefetch.max(1));
        let handle = std::thread::Builder::new()
            .name(format!("vtpose-loader-{}", source.split))
            .spawn(move || {
                // A send fails only when the receiver is gone: stop quietly then.
                let _ = run_passes(&mut source, &passes, &opts, batch_size, &tx);
                source
            })
            .expect("cannot start the loader thread");
        Loader { rx: Some(rx), handle: Some(handle) }
    }

    /// The next message; `None` when every pass is done.
    pub fn recv(&self) -> Option<Result<Loaded>> {
        self.rx.as_ref()?.recv().ok()
    }

    /// Stops the thread (if still running) and returns the source with its cache.
    pub fn finish(mut self) -> SplitSource {
        self.rx = None;
        self.handle.take().expect("finish once").join().expect("the loader thread panicked")
    }
}

fn run_passes(
    source: &mut SplitSource,
    passes: &[Pass],
    opts: &PrepareOptions,
    batch_size: usize,
    tx: &SyncSender<Result<Loaded>>,
) -> Result<(), ()> {
    let models = source.models.clone();
    for pass in passes {
        let mut batch = Batch::default();
        let mut skipped = Vec::new();
        for &i in &pass.order {
            let view = match source.view(i) {
                Ok(v) => v,
                Err(e) => {
                    tx.send(Err(e)).map_err(|_| ())?;
                    return Err(());
                }
            };
            if !view.visible() {
                skipped.push(view.index);
                continue;
            }
            batch.samples.push(prepare(&view, &models[view.object], opts, pass.epoch));
            if batch.len() == batch_size {
                tx.send(Ok(Loaded::Batch { epoch: pass.epoch, batch: std::mem::take(&mut batch) })).map_err(|_| ())?;
            }
        }
        if !batch.is_empty() {
            tx.send(Ok(Loaded::Batch { epoch: pass.epoch, batch })).map_err(|_| ())?;
        }
        tx.send(Ok(Loaded::EndOfPass { epoch: pass.epoch, skipped })).map_err(|_| ())?;
    }
    Ok(())
}

/// A seeded shuffle of `0..n` for `epoch`.
pub fn shuffled(n: usize, seed: u64, epoch: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(mix_seed(&[seed, epoch, 0x5_4ff1e])));
    order
}
