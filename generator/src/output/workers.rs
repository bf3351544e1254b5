//! The one worker pool of `generate`, `bench` and `grasps`: `jobs` threads, each with its own state
//! (a renderer and physics are made per thread, as neither is shared), taking the next item of a
//! list as they free up. The first error stops the pool from handing out more items; items already
//! started finish or notice the shared `abort` flag themselves (a shard checks it between samples).

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use anyhow::Result;

/// Results tagged with the index of the item they came from.
pub type Indexed<R> = Vec<(usize, R)>;

/// What a pool run gave back.
pub struct Pooled<R, F> {
    /// `(item index, result)` of every item whose work returned `Some`, in item order.
    pub results: Indexed<R>,
    /// Each worker's `finish` value (workers whose `init` failed or that found no work give none).
    pub finished: Vec<F>,
    /// The first error of any worker's `init`, `work` or `finish`.
    pub error: Option<anyhow::Error>,
}

impl<R, F> Pooled<R, F> {
    /// The results, or the first error.
    pub fn into_result(self) -> Result<(Indexed<R>, Vec<F>)> {
        match self.error {
            Some(e) => Err(e),
            None => Ok((self.results, self.finished)),
        }
    }
}

/// Runs `work(state, index, item)` over `items` on `jobs` threads. A worker makes its state with
/// `init` only once it has an item to work on (no renderer is made for an empty run), and hands it
/// to `finish` at the end. `abort` is set on the first error; callers may set it too.
pub fn run_pool<T, S, R, F>(
    jobs: usize,
    items: &[T],
    abort: &AtomicBool,
    init: impl Fn() -> Result<S> + Sync,
    work: impl Fn(&mut S, usize, &T) -> Result<Option<R>> + Sync,
    finish: impl Fn(S) -> Result<F> + Sync,
) -> Pooled<R, F>
where
    T: Sync,
    R: Send,
    F: Send,
{
    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    let finished = Mutex::new(Vec::new());
    let error: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    let fail = |e: anyhow::Error| {
        abort.store(true, Ordering::SeqCst);
        error.lock().expect("not poisoned").get_or_insert(e);
    };
    std::thread::scope(|scope| {
        for _ in 0..jobs.max(1).min(items.len().max(1)) {
            let (next, results, finished, init, work, finish, fail) = (&next, &results, &finished, &init, &work, &finish, &fail);
            scope.spawn(move || {
                let mut state = None;
                loop {
                    if abort.load(Ordering::SeqCst) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(item) = items.get(i) else { break };
                    if state.is_none() {
                        match init() {
                            Ok(s) => state = Some(s),
                            Err(e) => {
                                fail(e);
                                return;
                            }
                        }
                    }
                    match work(state.as_mut().expect("made above"), i, item) {
                        Ok(Some(r)) => results.lock().expect("not poisoned").push((i, r)),
                        Ok(None) => {}
                        Err(e) => {
                            fail(e);
                            break;
                        }
                    }
                }
                if let Some(s) = state {
                    match finish(s) {
                        Ok(f) => finished.lock().expect("not poisoned").push(f),
                        Err(e) => fail(e),
                    }
                }
            });
        }
    });
    let mut results = results.into_inner().expect("not poisoned");
    results.sort_by_key(|r| r.0);
    Pooled { results, finished: finished.into_inner().expect("not poisoned"), error: error.into_inner().expect("not poisoned") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_once_in_order_with_per_worker_state() {
        let items: Vec<u32> = (0..50).collect();
        let abort = AtomicBool::new(false);
        let made = AtomicUsize::new(0);
        let p = run_pool(
            3,
            &items,
            &abort,
            || {
                made.fetch_add(1, Ordering::SeqCst);
                Ok(0u32)
            },
            |seen: &mut u32, i, x| {
                *seen += 1;
                Ok((x % 7 != 0).then_some(i as u32 * 10 + x))
            },
            Ok,
        );
        let (results, finished) = p.into_result().unwrap();
        let expected: Vec<(usize, u32)> = items.iter().filter(|x| *x % 7 != 0).map(|&x| (x as usize, x * 11)).collect();
        assert_eq!(results, expected);
        // Every item was worked on by exactly one worker; at most 3 states were made.
        assert_eq!(finished.iter().sum::<u32>(), 50);
        assert!(made.load(Ordering::SeqCst) <= 3 && made.load(Ordering::SeqCst) == finished.len());
        assert!(!abort.load(Ordering::SeqCst));
    }

    #[test]
    fn the_first_error_stops_the_pool_and_no_state_is_made_without_work() {
        let items: Vec<u32> = (0..1000).collect();
        let abort = AtomicBool::new(false);
        // One worker: items 0..3 are done, 3 fails, nothing after it is started.
        let p = run_pool(
            1,
            &items,
            &abort,
            || Ok(()),
            |_, _, x| if *x == 3 { anyhow::bail!("item 3 is bad") } else { Ok(Some(*x)) },
            |_| Ok(()),
        );
        assert!(abort.load(Ordering::SeqCst));
        assert_eq!(p.error.as_ref().unwrap().to_string(), "item 3 is bad");
        assert_eq!(p.results, vec![(0, 0), (1, 1), (2, 2)]);
        let empty: Vec<u32> = Vec::new();
        let made = AtomicUsize::new(0);
        let abort = AtomicBool::new(false);
        let p = run_pool(
            4,
            &empty,
            &abort,
            || {
                made.fetch_add(1, Ordering::SeqCst);
                Ok(())
            },
            |_, _, x: &u32| Ok(Some(*x)),
            |_| Ok(()),
        );
        assert!(p.into_result().unwrap().0.is_empty());
        assert_eq!(made.load(Ordering::SeqCst), 0);
    }
}
