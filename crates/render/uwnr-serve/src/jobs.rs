//! The render pool: worker threads fed by a bounded queue of jobs.
//!
//! Each job belongs to a *view* (a cell of the page: a method and a reference). A newer
//! submission for a view makes its older jobs stale: a queued stale job is taken off the queue at
//! once (freeing its slot), and a running one finishes but its result is discarded. A full queue
//! refuses new jobs ([`ServeError::Busy`], answered `503`). Finished results are kept for the
//! latest jobs only, within a count and a byte budget; a view is remembered only while one of its
//! jobs waits or runs (at most the queue's capacity plus the workers), so memory stays bounded
//! however long the server runs and however many views clients name.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Instant;

use serde_json::{Value, json};

use crate::error::{Result, ServeError};

/// Finished jobs whose results are kept.
pub const KEPT_RESULTS: usize = 96;
/// Bytes of finished results kept (encoded PNGs).
pub const KEPT_RESULT_BYTES: usize = 128 * 1024 * 1024;

/// What a finished render gives.
#[derive(Clone, Debug)]
pub struct Output {
    /// The encoded image.
    pub png: Arc<Vec<u8>>,
    pub width: usize,
    pub height: usize,
    /// What the method recorded (drawn parameters, depth response).
    pub params: Value,
}

/// Where a job is.
#[derive(Clone, Debug)]
pub enum State {
    Queued,
    Running {
        since: Instant,
    },
    Done {
        output: Output,
        millis: u128,
    },
    Failed {
        message: String,
    },
    /// A newer request for the same view replaced it.
    Stale,
}

struct Job<T> {
    /// Emptied when the job is finished (the name may be as large as a request body).
    view: String,
    /// Taken by the worker that runs it.
    request: Option<T>,
    state: State,
}

struct Inner<T> {
    next_id: u64,
    queue: VecDeque<u64>,
    jobs: HashMap<u64, Job<T>>,
    /// The newest job of each view that has a job waiting or running (ids grow with time).
    latest: HashMap<String, u64>,
    /// Jobs no longer queued or running, oldest first.
    finished: VecDeque<u64>,
    stopping: bool,
}

/// Runs one request; an error is the message shown for the job.
pub type Runner<T> = dyn Fn(&T) -> std::result::Result<Output, String> + Send + Sync;

/// The pool (cheap to share: clone the `Arc` it lives in).
pub struct Pool<T> {
    inner: Mutex<Inner<T>>,
    ready: Condvar,
    capacity: usize,
    threads: Mutex<Vec<JoinHandle<()>>>,
}

impl<T: Send + 'static> Pool<T> {
    /// Starts `workers` threads running `runner`, with at most `capacity` jobs waiting.
    pub fn start(workers: usize, capacity: usize, runner: Arc<Runner<T>>) -> Result<Arc<Self>> {
        let pool = Arc::new(Self {
            inner: Mutex::new(Inner {
                next_id: 1,
                queue: VecDeque::new(),
                jobs: HashMap::new(),
                latest: HashMap::new(),
                finished: VecDeque::new(),
                stopping: false,
            }),
            ready: Condvar::new(),
            capacity: capacity.max(1),
            threads: Mutex::new(Vec::new()),
        });
        let mut threads = Vec::new();
        for i in 0..workers.max(1) {
            let pool = pool.clone();
            let runner = runner.clone();
            threads.push(
                std::thread::Builder::new()
                    .name(format!("uwnr-serve-render-{i}"))
                    .spawn(move || pool.work(runner.as_ref()))
                    .map_err(ServeError::io("starting a render thread"))?,
            );
        }
        *pool.threads.lock().unwrap_or_else(PoisonError::into_inner) = threads;
        Ok(pool)
    }

    fn lock(&self) -> MutexGuard<'_, Inner<T>> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Queues `request` for `view`, making older jobs of the view stale; the job's id.
    pub fn submit(&self, view: &str, request: T) -> Result<u64> {
        let mut g = self.lock();
        // Older queued jobs of this view will never be wanted: their slots count as free.
        let stale: Vec<u64> = g
            .queue
            .iter()
            .copied()
            .filter(|id| g.jobs.get(id).is_some_and(|j| j.view == view))
            .collect();
        if g.queue.len() - stale.len() >= self.capacity {
            return Err(ServeError::Busy {
                capacity: self.capacity,
            });
        }
        let id = g.next_id;
        g.next_id += 1;
        g.latest.insert(view.to_string(), id);
        for old in stale {
            g.queue.retain(|q| *q != old);
            finish(&mut g, old, State::Stale);
        }
        g.jobs.insert(
            id,
            Job {
                view: view.to_string(),
                request: Some(request),
                state: State::Queued,
            },
        );
        g.queue.push_back(id);
        drop(g);
        self.ready.notify_one();
        Ok(id)
    }

    /// The job's state and, while queued, how many jobs are ahead of it.
    pub fn state(&self, id: u64) -> Option<(State, usize)> {
        let g = self.lock();
        let job = g.jobs.get(&id)?;
        let ahead = g.queue.iter().position(|q| *q == id).unwrap_or(0);
        Some((job.state.clone(), ahead))
    }

    /// The state as the page reads it.
    pub fn status_json(&self, id: u64) -> Option<Value> {
        let (state, ahead) = self.state(id)?;
        Some(match state {
            State::Queued => json!({ "state": "queued", "ahead": ahead }),
            State::Running { since } => {
                json!({ "state": "running", "elapsed_ms": since.elapsed().as_millis() as u64 })
            }
            State::Done { output, millis } => json!({
                "state": "done",
                "millis": millis as u64,
                "width": output.width,
                "height": output.height,
                "params": output.params,
            }),
            State::Failed { message } => json!({ "state": "failed", "error": message }),
            State::Stale => json!({ "state": "stale" }),
        })
    }

    /// Numbers for the page and the load test: waiting, running, kept.
    pub fn counts(&self) -> (usize, usize, usize) {
        let g = self.lock();
        let running = g
            .jobs
            .values()
            .filter(|j| matches!(j.state, State::Running { .. }))
            .count();
        (g.queue.len(), running, g.finished.len())
    }

    /// Views the pool remembers (what memory the views' names take grows with).
    pub fn views(&self) -> usize {
        self.lock().latest.len()
    }

    /// The queue's capacity.
    #[must_use]
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Stops the workers after their current jobs.
    pub fn stop(&self) {
        self.lock().stopping = true;
        self.ready.notify_all();
        let threads =
            std::mem::take(&mut *self.threads.lock().unwrap_or_else(PoisonError::into_inner));
        for t in threads {
            let _ = t.join();
        }
    }

    fn work(&self, runner: &Runner<T>) {
        loop {
            let (id, request) = {
                let mut g = self.lock();
                loop {
                    if g.stopping {
                        return;
                    }
                    if let Some(id) = g.queue.pop_front() {
                        let Some(job) = g.jobs.get_mut(&id) else {
                            continue;
                        };
                        let Some(request) = job.request.take() else {
                            continue;
                        };
                        job.state = State::Running {
                            since: Instant::now(),
                        };
                        break (id, request);
                    }
                    g = self.ready.wait(g).unwrap_or_else(PoisonError::into_inner);
                }
            };
            let start = Instant::now();
            // A panic in a method is a failed render, not a dead worker.
            let result =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| runner(&request)))
                    .unwrap_or_else(
                        |_| Err("the render panicked (a bug: please report it)".into()),
                    );
            drop(request);
            let mut g = self.lock();
            let current = g
                .jobs
                .get(&id)
                .is_some_and(|job| g.latest.get(&job.view) == Some(&id));
            let state = match result {
                _ if !current => State::Stale,
                Ok(output) => State::Done {
                    output,
                    millis: start.elapsed().as_millis(),
                },
                Err(message) => State::Failed { message },
            };
            finish(&mut g, id, state);
        }
    }
}

/// The output of a finished job.
impl<T> Pool<T> {
    /// The output of job `id` once done.
    pub fn output(&self, id: u64) -> Option<Output> {
        let g = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        match &g.jobs.get(&id)?.state {
            State::Done { output, .. } => Some(output.clone()),
            _ => None,
        }
    }
}

/// Records `id`'s final state, forgets its view when it was the view's newest job, and evicts
/// the oldest finished jobs beyond the budgets.
fn finish<T>(g: &mut Inner<T>, id: u64, state: State) {
    if let Some(job) = g.jobs.get_mut(&id) {
        job.state = state;
        job.request = None;
        let view = std::mem::take(&mut job.view);
        if g.latest.get(&view) == Some(&id) {
            g.latest.remove(&view);
        }
        g.finished.push_back(id);
    }
    let bytes = |g: &Inner<T>| -> usize {
        g.finished
            .iter()
            .filter_map(|i| match &g.jobs.get(i)?.state {
                State::Done { output, .. } => Some(output.png.len()),
                _ => None,
            })
            .sum()
    };
    while g.finished.len() > KEPT_RESULTS || (g.finished.len() > 1 && bytes(g) > KEPT_RESULT_BYTES)
    {
        if let Some(old) = g.finished.pop_front() {
            g.jobs.remove(&old);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc;
    use std::time::Duration;

    use super::*;

    /// A pool whose runner waits for a go signal, so tests decide when renders finish.
    fn gated() -> (Arc<Pool<u32>>, mpsc::Sender<()>) {
        let (tx, rx) = mpsc::channel::<()>();
        let rx = Mutex::new(rx);
        let runner: Arc<Runner<u32>> = Arc::new(move |v: &u32| {
            rx.lock().unwrap().recv().map_err(|e| e.to_string())?;
            if *v == 13 {
                return Err("unlucky".into());
            }
            Ok(Output {
                png: Arc::new(vec![*v as u8]),
                width: 1,
                height: 1,
                params: json!({}),
            })
        });
        (Pool::start(1, 2, runner).unwrap(), tx)
    }

    /// Polls until `f` holds (a hang guard, not a timing assertion: 60 s).
    fn wait_until(pool: &Pool<u32>, id: u64, f: impl Fn(&State) -> bool) -> State {
        for _ in 0..30_000 {
            let (s, _) = pool.state(id).unwrap();
            if f(&s) {
                return s;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        panic!("job {id} never reached the state");
    }

    #[test]
    fn newer_requests_make_older_ones_stale_and_a_full_queue_refuses() {
        let (pool, go) = gated();
        let first = pool.submit("a", 1).unwrap();
        wait_until(&pool, first, |s| matches!(s, State::Running { .. }));
        // Queue capacity 2: two views wait, a third is refused.
        let b1 = pool.submit("b", 2).unwrap();
        let _c = pool.submit("c", 3).unwrap();
        assert!(matches!(
            pool.submit("d", 4),
            Err(ServeError::Busy { capacity: 2 })
        ));
        // A newer request for view b replaces the queued one, in its slot.
        let b2 = pool.submit("b", 5).unwrap();
        assert!(matches!(pool.state(b1).unwrap().0, State::Stale));
        // Refused while full, and the refusal changes nothing: view a's render stays current.
        assert!(matches!(pool.submit("a", 6), Err(ServeError::Busy { .. })));
        for _ in 0..3 {
            go.send(()).unwrap();
        }
        wait_until(&pool, first, |s| matches!(s, State::Done { .. }));
        let done = wait_until(&pool, b2, |s| matches!(s, State::Done { .. }));
        let State::Done { output, .. } = done else {
            unreachable!()
        };
        assert_eq!(*output.png, vec![5]);
        // A newer request for a running view makes the running one's result stale.
        let old = pool.submit("a", 8).unwrap();
        wait_until(&pool, old, |s| matches!(s, State::Running { .. }));
        let new = pool.submit("a", 9).unwrap();
        go.send(()).unwrap();
        go.send(()).unwrap();
        assert!(matches!(
            wait_until(&pool, old, |s| !matches!(s, State::Running { .. })),
            State::Stale
        ));
        wait_until(&pool, new, |s| matches!(s, State::Done { .. }));
        assert!(pool.output(old).is_none());
        drop(go);
        pool.stop();
    }

    #[test]
    fn a_failed_render_is_a_message_and_the_pool_goes_on() {
        let (pool, go) = gated();
        let bad = pool.submit("x", 13).unwrap();
        go.send(()).unwrap();
        let s = wait_until(&pool, bad, |s| matches!(s, State::Failed { .. }));
        assert!(matches!(s, State::Failed { message } if message == "unlucky"));
        let good = pool.submit("x", 7).unwrap();
        go.send(()).unwrap();
        wait_until(&pool, good, |s| matches!(s, State::Done { .. }));
        assert_eq!(*pool.output(good).unwrap().png, vec![7]);
        drop(go);
        pool.stop();
    }

    #[test]
    fn views_are_remembered_only_while_a_job_of_theirs_is_waiting_or_running() {
        let runner: Arc<Runner<u32>> = Arc::new(|v: &u32| {
            Ok(Output {
                png: Arc::new(vec![*v as u8]),
                width: 1,
                height: 1,
                params: json!({}),
            })
        });
        let (workers, capacity) = (2, 4);
        let pool = Pool::start(workers, capacity, runner).unwrap();
        // Unique view names of 60 kB, as a page (or a client) may send them.
        let long = "v".repeat(60 * 1024);
        for i in 0..500_u32 {
            let id = pool.submit(&format!("{i}-{long}"), i).unwrap();
            wait_until(&pool, id, |s| matches!(s, State::Done { .. }));
        }
        assert!(
            pool.views() <= capacity + workers,
            "{} views remembered",
            pool.views()
        );
        pool.stop();
    }
}
