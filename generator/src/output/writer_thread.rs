//! The writer stage on its own thread: encoding and zstd compression of sample N overlap the
//! scene, physics and rendering of sample N + 1. A bounded queue between the two keeps memory
//! constant (a worker that outruns the writer waits), and one queue keeps the order, so the shard
//! is byte-identical to writing in the worker.

use std::path::Path;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow};
use vt_dataset::{Compression, Sample, SceneModel, ShardMeta, ShardReceipt, ShardWriter};

/// Samples that may wait for the writer: enough to ride out a slow chunk flush, few enough that
/// the queue holds only a few megabytes.
pub const QUEUE_DEPTH: usize = 3;

enum Message {
    Scene(Vec<SceneModel>),
    Sample(Box<Sample>),
    Metadata(String, String),
    /// Complete the shard. A queue closed without it (an error or abort in the worker) leaves the
    /// shard `.partial`: an interrupted shard never looks complete.
    Finish,
}

/// How long a writer thread worked: busy (wall-clock, from a message's arrival to its end) and
/// its CPU time (encoding, compression, writing).
#[derive(Debug, Clone, Copy, Default)]
pub struct WriterTimes {
    pub busy: Duration,
    pub cpu: Duration,
}

/// A `ShardWriter` running on a thread of its own.
pub struct WriterThread {
    tx: Option<SyncSender<Message>>,
    handle: Option<JoinHandle<Result<(ShardReceipt, WriterTimes)>>>,
}

impl WriterThread {
    pub fn create(path: &Path, meta: &ShardMeta, compression: Compression) -> Result<Self> {
        let mut writer = ShardWriter::create(path, meta, compression)?;
        let (tx, rx): (SyncSender<Message>, Receiver<Message>) = sync_channel(QUEUE_DEPTH);
        let shown = path.display().to_string();
        let handle = std::thread::Builder::new()
            .name("vtgen-writer".into())
            .spawn(move || -> Result<(ShardReceipt, WriterTimes)> {
                let cpu0 = crate::cpu_clock::thread_cpu_time();
                let mut busy = Duration::ZERO;
                for m in rx {
                    let t0 = Instant::now();
                    match m {
                        Message::Scene(models) => writer.set_scene(models),
                        Message::Sample(s) => writer.write_sample(&s).with_context(|| format!("writing {shown}"))?,
                        Message::Metadata(k, v) => writer.set_metadata(&k, v),
                        Message::Finish => {
                            let receipt = writer.finish().with_context(|| format!("finishing {shown}"))?;
                            let times = WriterTimes { busy: busy + t0.elapsed(), cpu: crate::cpu_clock::cpu_since(cpu0) };
                            return Ok((receipt, times));
                        }
                    }
                    busy += t0.elapsed();
                }
                Err(anyhow!("{shown}: abandoned before it was complete"))
            })
            .context("cannot start the writer thread")?;
        Ok(WriterThread { tx: Some(tx), handle: Some(handle) })
    }

    fn send(&mut self, m: Message) -> Result<()> {
        let tx = self.tx.as_ref().expect("open until finish");
        if tx.send(m).is_err() {
            // The writer stopped on an error: report it.
            return Err(self.join().err().unwrap_or_else(|| anyhow!("the writer thread stopped")));
        }
        Ok(())
    }

    pub fn set_scene(&mut self, models: Vec<SceneModel>) -> Result<()> {
        self.send(Message::Scene(models))
    }

    pub fn write_sample(&mut self, sample: Sample) -> Result<()> {
        self.send(Message::Sample(Box::new(sample)))
    }

    pub fn set_metadata(&mut self, key: &str, value: String) -> Result<()> {
        self.send(Message::Metadata(key.into(), value))
    }

    fn join(&mut self) -> Result<(ShardReceipt, WriterTimes)> {
        self.tx = None;
        match self.handle.take() {
            Some(h) => h.join().map_err(|_| anyhow!("the writer thread panicked"))?,
            None => Err(anyhow!("the writer thread already stopped")),
        }
    }

    /// Waits for the queue to drain and the shard to be complete (renamed into place). Returns
    /// the receipt and how long the writer worked.
    pub fn finish(mut self) -> Result<(ShardReceipt, WriterTimes)> {
        self.send(Message::Finish)?;
        self.join()
    }
}

impl Drop for WriterThread {
    /// Dropped unfinished (an error or an abort in the worker): the writer stops without
    /// completing, and its shard stays `.partial`.
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
