//! UWNR's batches, the [`BatchSource`] its runs draw from (on uwnr-run's prefetching thread);
//! the samples of a batch are prepared in parallel (rayon).
//!
//! Batch `k` of epoch `e` holds the samples at positions `k * batch .. (k + 1) * batch` of the
//! epoch's order ([`uwnr_run::plan::epoch_order`]); the incomplete last batch of an epoch is
//! dropped so every step sees the same batch size. Because each sample is a pure function of
//! `(seed, epoch, position)`, the stream does not depend on thread timing and can be restarted
//! at any batch.

use std::sync::Arc;

use rayon::prelude::*;
use uwnr_core::lightfield::LightFieldMap;

use uwnr_model::Variant;

use uwnr_run::BatchSource;
use uwnr_run::plan::epoch_order;

use crate::augment::{Sample, TARGET_CHANNELS, WATER_VALUES, make_sample, plan_sample};
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
    /// The anchored variant's detail retention (the model config's `detail_retention`).
    pub detail_retention: bool,
    /// What the anchored variant's anchor starts from (the model config's `anchor`).
    pub anchor: uwnr_model::AnchorKind,
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
        let start = index * self.batch_size;
        let positions = start..start + self.batch_size;
        if positions.end > order.len() {
            return Err(uwnr_run::RunError::Loader(format!(
                "batch {index} of epoch {epoch} needs positions up to {}, the epoch has {}",
                positions.end,
                order.len()
            ))
            .into());
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
                    (pi, pair.width(), pair.height()),
                    self.crop,
                    &self.augment,
                );
                make_sample(
                    pair,
                    &plan,
                    self.crop,
                    (self.variant, self.detail_retention, self.anchor),
                    |im| Ok(uwnr_core::lightfield::light_field_raw_with(im, map)?),
                )
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

impl BatchSource for BatchSpec {
    type Batch = Batch;
    type Error = TrainError;

    fn batches_per_epoch(&self) -> usize {
        BatchSpec::batches_per_epoch(self)
    }

    fn batch(&self, epoch: usize, index: usize) -> Result<Batch> {
        BatchSpec::batch(self, epoch, index)
    }
}
