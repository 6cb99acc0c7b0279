//! uwnr-run: training runs for any uwnr network. It knows runs, not networks: a trainer is a
//! small [`Task`] (build the network, take a step on a batch, validate, export weights) plus a
//! [`BatchSource`], and this crate gives it everything else, one way for every network:
//!
//! - [`pairs`]: paired-folder discovery, decoding with one size rule, the 8-bit pair store and
//!   the data report;
//! - [`plan`]: the seeded data order and crop/flip/rotation of each sample, pure functions of
//!   `(seed, epoch, position)`;
//! - [`folder`]: the run folder's layout and lifecycle (claimed only once the data has loaded),
//!   the run's config with the changed fields named on a refused resume;
//! - [`checkpoint`]: atomic `last` and `best` checkpoints (burnpack model and optimiser, state,
//!   the network's own weights file) and exact resume;
//! - [`csvlog`], [`plot`]: `metrics.csv`, `val.csv`, `curves.png` and contact sheets;
//! - [`loader`]: the prefetching batch thread, which keeps a panic's cause;
//! - [`settings`]: the run-level settings every trainer's config holds ([`RunSettings`]: seed,
//!   logging, validation, checkpoint and prefetch cadence), checked and scheduled once;
//! - [`device`]: the burn devices, by name;
//! - [`learner`]: the loop ([`train`]), with step and time checkpoint intervals and a clean stop.
//!
//! burn appears only where a network is saved, loaded or seeded.

pub mod checkpoint;
pub mod csvlog;
pub mod device;
pub mod error;
pub mod folder;
pub mod learner;
pub mod loader;
pub mod pairs;
pub mod plan;
pub mod plot;
pub mod settings;

pub use device::{Device, UnknownDevice, device_from_name, device_names};
pub use error::{Result, RunError};
pub use learner::{
    Event, Prepared, Schedule, Scores, Session, Summary, Task, TrainOptions, ValResult,
    init_seeded, train,
};
pub use loader::BatchSource;
pub use settings::{InvalidSetting, RunSettings};
