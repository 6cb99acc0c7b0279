//! The batch producer: a thread that prepares batches ahead of the training step and hands
//! them over a bounded channel; the samples of a batch are prepared in parallel (rayon).
//!
//! Batch `k` of epoch `e` holds the samples at positions `k * batch .. (k + 1) * batch` of the
//! epoch's order ([`crate::augment::epoch_order`]); the incomplete last batch of an epoch is
//! dropped so every step sees the same batch size. Because each sample is a pure function of
//! `(seed, epoch, position)`, the stream does not depend on thread timing and can be restarted
//! at any batch.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use rayon::prelude::*;
use uwnr_core::lightfield::LightFieldMap;

use uwnr_model::Variant;

use crate::augment::{
    Sample, TARGET_CHANNELS, WATER_VALUES, epoch_order, make_sample, plan_sample,
};
use crate::config::AugmentConfig;
use crate::data::PairData;
use crate::error::{Result, TrainError};

/// A batch ready for the network.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Epoch (0-based).
    pub epoch: usize,
    /// Batch index within the epoch.
    pub index: usize,
    /// Samples in the batch.
    pub size: usize,
    /// Crop side.
    pub crop: usize,
    /// `[size, channels, crop, crop]`, row-major (7 channels for the paper's variant, 9 for
    /// the anchored one).
    pub input: Vec<f32>,
    /// `[size, 3, crop, crop]`, row-major.
    pub target: Vec<f32>,
    /// `[size, 1, crop, crop]` (anchored variant; empty otherwise).
    pub depth: Vec<f32>,
    /// `[size, 6]`: veil RGB, beta RGB per sample (anchored variant; zeros otherwise).
    pub water: Vec<f32>,
}

/// What the producer needs to build batches.
#[derive(Clone)]
pub struct BatchSpec {
    /// Training pairs.
    pub pairs: Arc<Vec<PairData>>,
    /// Seed of order and augmentation.
    pub seed: u64,
    /// Samples per batch.
    pub batch_size: usize,
    /// Crop side.
    pub crop: usize,
    /// Augmentation.
    pub augment: AugmentConfig,
    /// How the light field of an underwater crop is normalised (computed at the crop's size).
    pub light_field: LightFieldMap,
    /// What the network's planes mean.
    pub variant: Variant,
}

impl BatchSpec {
    /// Full batches per epoch.
    #[must_use]
    pub fn batches_per_epoch(&self) -> usize {
        self.pairs.len() / self.batch_size.max(1)
    }

    /// Builds batch `index` of epoch `epoch` (pure: the same arguments give the same batch).
    pub fn batch(&self, epoch: usize, index: usize) -> Result<Batch> {
        let order = epoch_order(self.seed, epoch, self.pairs.len());
        self.batch_with_order(&order, epoch, index)
    }

    fn batch_with_order(&self, order: &[usize], epoch: usize, index: usize) -> Result<Batch> {
        let start = index * self.batch_size;
        let positions = start..start + self.batch_size;
        if positions.end > order.len() {
            return Err(TrainError::Loader(format!(
                "batch {index} of epoch {epoch} needs positions up to {}, the epoch has {}",
                positions.end,
                order.len()
            )));
        }
        let map = self.light_field;
        let samples: Vec<Result<Sample>> = positions
            .into_par_iter()
            .map(|pos| {
                let pi = order[pos];
                let pair = &self.pairs[pi];
                let plan = plan_sample(
                    self.seed,
                    epoch,
                    pos,
                    (pi, pair.width, pair.height),
                    self.crop,
                    &self.augment,
                );
                make_sample(pair, &plan, self.crop, self.variant, |im| {
                    Ok(uwnr_core::lightfield::light_field_raw_with(im, map)?)
                })
            })
            .collect();
        let n = self.crop * self.crop;
        let mut input = Vec::with_capacity(self.batch_size * self.variant.channels().0 * n);
        let mut target = Vec::with_capacity(self.batch_size * TARGET_CHANNELS * n);
        let mut depth = Vec::new();
        let mut water = Vec::with_capacity(self.batch_size * WATER_VALUES);
        for s in samples {
            let s = s?;
            input.extend_from_slice(&s.input);
            target.extend_from_slice(&s.target);
            depth.extend_from_slice(&s.depth);
            water.extend_from_slice(&s.water);
        }
        Ok(Batch {
            epoch,
            index,
            size: self.batch_size,
            crop: self.crop,
            input,
            target,
            depth,
            water,
        })
    }
}

/// The running producer. Dropping it stops the thread.
pub struct Loader {
    rx: Option<Receiver<Result<Batch>>>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
    started: bool,
}

impl Loader {
    /// Starts producing from batch `start_index` of epoch `start_epoch` up to the end of epoch
    /// `end_epoch - 1`, keeping at most `prefetch` batches ready.
    pub fn start(
        spec: BatchSpec,
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
            .spawn(move || produce(&spec, start_epoch, start_index, end_epoch, &tx, &flag))
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
    pub fn next_batch(&mut self) -> Option<Result<Batch>> {
        if !self.started {
            return Some(Err(TrainError::Loader(
                "the loader thread could not be started".into(),
            )));
        }
        match self.rx.as_ref()?.recv() {
            Ok(batch) => Some(batch),
            // The producer has returned or unwound: join it to learn which.
            Err(_) => match self.handle.take()?.join() {
                Ok(()) => None,
                Err(payload) => Some(Err(TrainError::Loader(format!(
                    "the loader thread panicked: {}",
                    panic_message(payload.as_ref())
                )))),
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

impl Drop for Loader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver unblocks a producer waiting on a full channel.
        self.rx = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn produce(
    spec: &BatchSpec,
    start_epoch: usize,
    start_index: usize,
    end_epoch: usize,
    tx: &SyncSender<Result<Batch>>,
    stop: &AtomicBool,
) {
    let per_epoch = spec.batches_per_epoch();
    for epoch in start_epoch..end_epoch {
        let order = epoch_order(spec.seed, epoch, spec.pairs.len());
        let first = if epoch == start_epoch { start_index } else { 0 };
        for index in first..per_epoch {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let batch = spec.batch_with_order(&order, epoch, index);
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

    /// A pair whose buffers are shorter than its size says: building a sample from it panics
    /// (an index out of bounds), inside the producer thread.
    fn malformed_pair() -> PairData {
        PairData {
            name: "short".into(),
            width: 64,
            height: 64,
            clean: vec![0; 3],
            underwater: vec![0; 3],
            depth: vec![0; 1],
        }
    }

    #[test]
    fn a_panic_in_the_producer_is_reported_with_its_cause() {
        let spec = BatchSpec {
            pairs: Arc::new(vec![malformed_pair(), malformed_pair()]),
            seed: 1,
            batch_size: 2,
            crop: 32,
            augment: AugmentConfig::default(),
            light_field: LightFieldMap::default(),
            variant: Variant::Paper,
        };
        let mut loader = Loader::start(spec, 0, 0, 1, 1);
        let err = match loader.next_batch() {
            Some(Err(e)) => e.to_string(),
            Some(Ok(_)) => panic!("a batch from a malformed pair"),
            None => panic!("the panic read as the end of the data"),
        };
        assert!(err.contains("panicked") && err.contains("out of"), "{err}");
        // Afterwards the stream is over, not an endless error.
        assert!(loader.next_batch().is_none());
    }

    #[test]
    fn the_stream_ends_after_the_last_epoch() {
        let pair = PairData {
            name: "ok".into(),
            width: 32,
            height: 32,
            clean: vec![128; 3 * 32 * 32],
            underwater: vec![64; 3 * 32 * 32],
            depth: vec![1000; 32 * 32],
        };
        let spec = BatchSpec {
            pairs: Arc::new(vec![pair.clone(), pair]),
            seed: 1,
            batch_size: 1,
            crop: 32,
            augment: AugmentConfig::default(),
            light_field: LightFieldMap::default(),
            variant: Variant::Paper,
        };
        let mut loader = Loader::start(spec, 0, 0, 2, 2);
        let got: Vec<(usize, usize)> = std::iter::from_fn(|| loader.next_batch())
            .map(|b| b.map(|b| (b.epoch, b.index)).unwrap())
            .collect();
        assert_eq!(got, [(0, 0), (0, 1), (1, 0), (1, 1)]);
    }
}
