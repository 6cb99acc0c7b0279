//! The batch producer: a thread that prepares batches ahead of the training step and hands
//! them over a bounded channel.
//!
//! Because a task's batch `k` of epoch `e` is a pure function of `(seed, e, k)`
//! ([`BatchSource::batch`]), the stream does not depend on thread timing and can be restarted
//! at any batch, which is what exact resume needs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use crate::error::RunError;

/// Where a task's batches come from. Implementations prepare the samples of a batch in
/// parallel (rayon) if they like; the loader runs them on its own thread.
pub trait BatchSource: Send + Sync + 'static {
    /// A batch ready for the network.
    type Batch: Send + 'static;
    /// The error of a batch that cannot be built.
    type Error: From<RunError> + Send + 'static;

    /// Full batches per epoch.
    fn batches_per_epoch(&self) -> usize;

    /// Builds batch `index` of epoch `epoch` (pure: the same arguments give the same batch).
    fn batch(&self, epoch: usize, index: usize) -> Result<Self::Batch, Self::Error>;
}

/// A batch and where it stands in the run.
#[derive(Debug)]
pub struct Positioned<B> {
    /// Epoch (0-based).
    pub epoch: usize,
    /// Index of the batch within the epoch.
    pub index: usize,
    /// The batch.
    pub batch: B,
}

/// What the channel carries.
type Item<S> = Result<Positioned<<S as BatchSource>::Batch>, <S as BatchSource>::Error>;

/// The running producer. Dropping it stops the thread.
pub struct Loader<S: BatchSource> {
    rx: Option<Receiver<Item<S>>>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
    started: bool,
}

impl<S: BatchSource> Loader<S> {
    /// Starts producing from batch `start_index` of epoch `start_epoch` up to the end of epoch
    /// `end_epoch - 1`, keeping at most `prefetch` batches ready.
    pub fn start(
        source: Arc<S>,
        start_epoch: usize,
        start_index: usize,
        end_epoch: usize,
        prefetch: usize,
    ) -> Self {
        let (tx, rx) = sync_channel(prefetch.max(1));
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::Builder::new()
            .name("uwnr-batches".into())
            .spawn(move || produce(&*source, start_epoch, start_index, end_epoch, &tx, &flag))
            .ok();
        Self {
            rx: Some(rx),
            stop,
            started: handle.is_some(),
            handle,
        }
    }

    /// The next batch, or `None` after the last epoch. A producer that panicked gives its
    /// panic message as the error (the channel closing alone would read as the end of the data).
    pub fn next_batch(&mut self) -> Option<Item<S>> {
        if !self.started {
            self.started = true;
            self.rx = None;
            return Some(Err(RunError::Loader(
                "the loader thread could not be started".into(),
            )
            .into()));
        }
        match self.rx.as_ref()?.recv() {
            Ok(batch) => Some(batch),
            // The producer has returned or unwound: join it to learn which.
            Err(_) => match self.handle.take()?.join() {
                Ok(()) => None,
                Err(payload) => Some(Err(RunError::Loader(format!(
                    "the loader thread panicked: {}",
                    panic_message(payload.as_ref())
                ))
                .into())),
            },
        }
    }
}

/// The text of a panic payload (`panic!` with a literal gives `&str`, with arguments `String`).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

impl<S: BatchSource> Drop for Loader<S> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver unblocks a producer waiting on a full channel.
        self.rx = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn produce<S: BatchSource>(
    source: &S,
    start_epoch: usize,
    start_index: usize,
    end_epoch: usize,
    tx: &SyncSender<Item<S>>,
    stop: &AtomicBool,
) {
    let per_epoch = source.batches_per_epoch();
    for epoch in start_epoch..end_epoch {
        let first = if epoch == start_epoch { start_index } else { 0 };
        for index in first..per_epoch {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let batch = source.batch(epoch, index).map(|batch| Positioned {
                epoch,
                index,
                batch,
            });
            let failed = batch.is_err();
            if tx.send(batch).is_err() || failed {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches are `(epoch, index)`; `panic_at` makes that batch panic inside the producer.
    struct Counting {
        per_epoch: usize,
        panic_at: Option<(usize, usize)>,
    }

    impl BatchSource for Counting {
        type Batch = (usize, usize);
        type Error = RunError;

        fn batches_per_epoch(&self) -> usize {
            self.per_epoch
        }

        fn batch(&self, epoch: usize, index: usize) -> Result<(usize, usize), RunError> {
            if self.panic_at == Some((epoch, index)) {
                let v: Vec<u8> = Vec::new();
                let _ = v[index + 7]; // index out of bounds
            }
            Ok((epoch, index))
        }
    }

    #[test]
    fn a_panic_in_the_producer_is_reported_with_its_cause() {
        let source = Arc::new(Counting {
            per_epoch: 2,
            panic_at: Some((0, 0)),
        });
        let mut loader = Loader::start(source, 0, 0, 1, 1);
        let err = match loader.next_batch() {
            Some(Err(e)) => e.to_string(),
            Some(Ok(_)) => panic!("a batch from the failing position"),
            None => panic!("the panic read as the end of the data"),
        };
        assert!(err.contains("panicked") && err.contains("out of"), "{err}");
        // Afterwards the stream is over, not an endless error.
        assert!(loader.next_batch().is_none());
    }

    #[test]
    fn the_stream_starts_where_asked_and_ends_after_the_last_epoch() {
        let source = Arc::new(Counting {
            per_epoch: 2,
            panic_at: None,
        });
        let mut loader = Loader::start(source, 0, 1, 2, 2);
        let got: Vec<(usize, usize)> = std::iter::from_fn(|| loader.next_batch())
            .map(|b| b.unwrap().batch)
            .collect();
        assert_eq!(got, [(0, 1), (1, 0), (1, 1)]);
    }
}
