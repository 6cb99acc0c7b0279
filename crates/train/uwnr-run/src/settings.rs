//! [`RunSettings`]: the run-level settings every trainer's config holds alike (seed, logging,
//! validation, checkpoint and prefetch cadence), checked once ([`RunSettings::validate`]) and
//! handed to the loop whole, in its [`crate::Schedule`] ([`crate::Schedule::new`]).
//!
//! A trainer's config embeds them flattened, so that its `config.json` keeps these keys at the
//! top level as before they were gathered here, and reads them over its own defaults (the
//! trainers differ in their default seed and validation interval):
//!
//! ```
//! use serde::{Deserialize, Deserializer, Serialize};
//! use uwnr_run::RunSettings;
//!
//! #[derive(Debug, PartialEq, Serialize, Deserialize)]
//! #[serde(default, deny_unknown_fields)]
//! struct MyConfig {
//!     epochs: usize,
//!     #[serde(flatten, deserialize_with = "run_settings")]
//!     run: RunSettings,
//! }
//!
//! impl Default for MyConfig {
//!     fn default() -> Self {
//!         Self { epochs: 10, run: RunSettings::defaults(7, 1) }
//!     }
//! }
//!
//! /// The run settings of a `MyConfig` file, over `MyConfig`'s defaults.
//! fn run_settings<'de, D: Deserializer<'de>>(d: D) -> Result<RunSettings, D::Error> {
//!     RunSettings::deserialize_over(MyConfig::default().run, d)
//! }
//!
//! let c: MyConfig = serde_json::from_str(r#"{"epochs": 3, "log_every_steps": 1}"#).unwrap();
//! assert_eq!((c.epochs, c.run.log_every_steps, c.run.seed), (3, 1, 7));
//! assert!(serde_json::from_str::<MyConfig>(r#"{"sead": 3}"#).is_err());
//! ```

use std::fmt;

use serde::de::{Error as _, IgnoredAny, MapAccess, Visitor};
use serde::{Deserializer, Serialize};

/// Default [`RunSettings::log_every_steps`].
pub const DEFAULT_LOG_EVERY_STEPS: usize = 10;
/// Default [`RunSettings::checkpoint_every_secs`]: a quarter of an hour.
pub const DEFAULT_CHECKPOINT_EVERY_SECS: u64 = 900;
/// Default [`RunSettings::prefetch_batches`].
pub const DEFAULT_PREFETCH_BATCHES: usize = 2;
/// Default [`RunSettings::val_sheet_pairs`].
pub const DEFAULT_VAL_SHEET_PAIRS: usize = 4;

/// How a run is seeded, logged, validated, checkpointed and fed: what every trainer's config
/// holds alike and means alike. Its keys sit at the top level of the config's JSON (the config
/// embeds it with `#[serde(flatten)]`, see the module docs).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RunSettings {
    /// Seed of the run: the initial weights, the data order, the crops and whatever else the
    /// trainer draws (recorded in the state; a resume must use the same).
    pub seed: u64,
    /// Validate every this many epochs (0 = never); the last epoch is always validated.
    pub val_every_epochs: usize,
    /// Write a row of `metrics.csv` every this many steps (the mean over them).
    pub log_every_steps: usize,
    /// Write the `last` checkpoint every this many steps (0 = only at epoch ends, on time and
    /// when the session ends).
    pub checkpoint_every_steps: usize,
    /// Write the `last` checkpoint when this many seconds of wall time have passed since the
    /// previous one (0 = never on time).
    pub checkpoint_every_secs: u64,
    /// Batches prepared ahead of the training step on the loader thread.
    pub prefetch_batches: usize,
    /// Validation pairs (or renders) shown in each contact sheet (`val/step-N.png`; 0 = none).
    pub val_sheet_pairs: usize,
}

/// The JSON keys of [`RunSettings`], in the order its fields serialise.
pub const RUN_SETTINGS_KEYS: [&str; 7] = [
    "seed",
    "val_every_epochs",
    "log_every_steps",
    "checkpoint_every_steps",
    "checkpoint_every_secs",
    "prefetch_batches",
    "val_sheet_pairs",
];

/// A run-level setting that would make a run fail; the trainers report it as their own
/// invalid-config error, naming the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct InvalidSetting {
    /// The field's JSON key.
    pub field: &'static str,
    /// What is wrong with its value.
    pub reason: String,
}

impl RunSettings {
    /// The defaults every trainer shares, with the trainer's own `seed` and `val_every_epochs`:
    /// a `metrics.csv` row every 10 steps, the `last` checkpoint every 15 minutes (and at epoch
    /// ends), 2 batches prefetched, 4 pairs in each contact sheet.
    #[must_use]
    pub fn defaults(seed: u64, val_every_epochs: usize) -> Self {
        Self {
            seed,
            val_every_epochs,
            log_every_steps: DEFAULT_LOG_EVERY_STEPS,
            checkpoint_every_steps: 0,
            checkpoint_every_secs: DEFAULT_CHECKPOINT_EVERY_SECS,
            prefetch_batches: DEFAULT_PREFETCH_BATCHES,
            val_sheet_pairs: DEFAULT_VAL_SHEET_PAIRS,
        }
    }

    /// Checks every setting that could make a run fail late; the error names the field.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        let at_least_one = |field: &'static str, v: usize| {
            if v == 0 {
                Err(InvalidSetting {
                    field,
                    reason: "must be at least 1".into(),
                })
            } else {
                Ok(())
            }
        };
        at_least_one("log_every_steps", self.log_every_steps)?;
        at_least_one("prefetch_batches", self.prefetch_batches)
    }

    /// Reads the settings from the (flattened) keys of a config over `defaults`: a key that is
    /// absent keeps its default, so a config reads its files as it did when these fields were
    /// its own with `#[serde(default)]`. For `#[serde(flatten, deserialize_with = ...)]`
    /// (module docs); a key given twice is an error, as it is for a derived struct. (A derived
    /// `Deserialize` could hold only one set of defaults: serde reads a flattened field from the
    /// remaining keys, never from the enclosing config's `Default`.)
    pub fn deserialize_over<'de, D: Deserializer<'de>>(
        defaults: Self,
        deserializer: D,
    ) -> Result<Self, D::Error> {
        deserializer.deserialize_struct("RunSettings", &RUN_SETTINGS_KEYS, Over(defaults))
    }
}

/// Deserialises [`RunSettings`] over defaults.
struct Over(RunSettings);

impl<'de> Visitor<'de> for Over {
    type Value = RunSettings;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the run settings of a training config")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RunSettings, A::Error> {
        let mut s = self.0;
        let mut seen = [false; RUN_SETTINGS_KEYS.len()];
        while let Some(key) = map.next_key::<String>()? {
            let Some(i) = RUN_SETTINGS_KEYS.iter().position(|k| *k == key) else {
                // Not ours: the enclosing config decides whether it is known.
                map.next_value::<IgnoredAny>()?;
                continue;
            };
            if std::mem::replace(&mut seen[i], true) {
                return Err(A::Error::duplicate_field(RUN_SETTINGS_KEYS[i]));
            }
            match i {
                0 => s.seed = map.next_value()?,
                1 => s.val_every_epochs = map.next_value()?,
                2 => s.log_every_steps = map.next_value()?,
                3 => s.checkpoint_every_steps = map.next_value()?,
                4 => s.checkpoint_every_secs = map.next_value()?,
                5 => s.prefetch_batches = map.next_value()?,
                _ => s.val_sheet_pairs = map.next_value()?,
            }
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn over(json: &str) -> serde_json::Result<RunSettings> {
        RunSettings::deserialize_over(
            RunSettings::defaults(41, 10),
            &mut serde_json::Deserializer::from_str(json),
        )
    }

    #[test]
    fn keys_are_the_fields_and_every_field_reads_back() {
        let s = RunSettings {
            seed: 1,
            val_every_epochs: 2,
            log_every_steps: 3,
            checkpoint_every_steps: 4,
            checkpoint_every_secs: 5,
            prefetch_batches: 6,
            val_sheet_pairs: 7,
        };
        let json = serde_json::to_string(&s).unwrap();
        let value: serde_json::Value = serde_json::from_str(&json).unwrap();
        let keys: Vec<&str> = value
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = RUN_SETTINGS_KEYS.to_vec();
        want.sort_unstable();
        assert_eq!(keys, want);
        assert_eq!(over(&json).unwrap(), s);
    }

    #[test]
    fn absent_keys_keep_the_defaults_and_bad_values_are_refused() {
        assert_eq!(over("{}").unwrap(), RunSettings::defaults(41, 10));
        let s = over(r#"{"log_every_steps": 1, "other": [1, 2]}"#).unwrap();
        assert_eq!(s.log_every_steps, 1);
        assert_eq!(s.seed, 41);
        for bad in [
            r#"{"seed": -1}"#,
            r#"{"seed": null}"#,
            r#"{"prefetch_batches": "2"}"#,
            r#"{"seed": 1, "seed": 2}"#,
        ] {
            assert!(over(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn validate_names_the_field() {
        RunSettings::defaults(0, 0).validate().unwrap();
        for (s, field) in [
            (
                RunSettings {
                    log_every_steps: 0,
                    ..RunSettings::defaults(0, 1)
                },
                "log_every_steps",
            ),
            (
                RunSettings {
                    prefetch_batches: 0,
                    ..RunSettings::defaults(0, 1)
                },
                "prefetch_batches",
            ),
        ] {
            assert_eq!(s.validate().unwrap_err().field, field);
        }
    }
}
