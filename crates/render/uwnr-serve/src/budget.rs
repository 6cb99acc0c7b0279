//! Memory counted in bytes: what the server's requests and renders may hold at once.
//!
//! Every allocation that grows with an image (a request body, a decoded image, a render's
//! planes) first takes a [`Lease`] of its estimated bytes from the one [`Budget`]; the lease is
//! returned when it is dropped. A request that cannot get its bytes within a short wait is
//! answered `503` (the page retries); a render waits for its bytes (its queue is bounded);
//! anything larger than the whole budget is refused with the sizes in the message. So however
//! many clients send whatever images, the bytes in flight stay within the budget.

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

use crate::error::{Result, ServeError};

/// A byte budget shared by everything in flight.
#[derive(Debug)]
pub struct Budget {
    total: u64,
    used: Mutex<u64>,
    freed: Condvar,
}

/// Bytes taken from a [`Budget`], given back when dropped.
#[derive(Debug)]
pub struct Lease {
    budget: Arc<Budget>,
    bytes: u64,
}

impl Lease {
    /// The bytes held.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl Drop for Lease {
    fn drop(&mut self) {
        let mut used = self.budget.lock();
        *used = used.saturating_sub(self.bytes);
        self.budget.freed.notify_all();
    }
}

impl Budget {
    /// A budget of `total` bytes.
    #[must_use]
    pub fn new(total: u64) -> Arc<Self> {
        Arc::new(Self {
            total,
            used: Mutex::new(0),
            freed: Condvar::new(),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, u64> {
        self.used.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The whole budget, bytes.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Bytes held now.
    #[must_use]
    pub fn used(&self) -> u64 {
        *self.lock()
    }

    /// Takes `bytes` for `what`, waiting at most `wait` for others to give theirs back:
    /// [`ServeError::TooBig`] when `bytes` exceeds the whole budget, [`ServeError::NoMemory`]
    /// when the wait ends first.
    pub fn take(self: &Arc<Self>, bytes: u64, what: &str, wait: Duration) -> Result<Lease> {
        if bytes > self.total {
            return Err(ServeError::TooBig {
                what: what.to_string(),
                bytes,
                budget: self.total,
            });
        }
        let deadline = Instant::now() + wait;
        let mut used = self.lock();
        while *used + bytes > self.total {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(ServeError::NoMemory {
                    what: what.to_string(),
                    bytes,
                });
            }
            used = self
                .freed
                .wait_timeout(used, left)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
        *used += bytes;
        Ok(Lease {
            budget: self.clone(),
            bytes,
        })
    }

    /// Takes `bytes` only if they are free now (what the HTTP side uses: it never blocks).
    pub fn try_take(self: &Arc<Self>, bytes: u64, what: &str) -> Result<Lease> {
        self.take(bytes, what, Duration::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leases_add_up_to_the_total_and_come_back_when_dropped() {
        let b = Budget::new(100);
        let a = b.try_take(60, "a").unwrap();
        assert_eq!(b.used(), 60);
        let e = b.try_take(41, "b").unwrap_err();
        assert!(matches!(e, ServeError::NoMemory { .. }), "{e}");
        assert_eq!(e.status(), 503);
        let c = b.try_take(40, "c").unwrap();
        assert_eq!(b.used(), 100);
        drop(a);
        assert_eq!(b.used(), 40);
        assert!(b.try_take(60, "d").is_ok());
        drop(c);
        assert_eq!(b.used(), 0);
    }

    #[test]
    fn more_than_the_whole_budget_is_refused_at_once_with_the_sizes() {
        let b = Budget::new(1000);
        let e = b
            .take(1001, "an image", Duration::from_secs(60))
            .unwrap_err();
        assert!(matches!(e, ServeError::TooBig { .. }));
        assert_eq!(e.status(), 413);
        assert!(e.to_string().contains("1001"), "{e}");
    }

    #[test]
    fn a_waiting_take_gets_bytes_given_back_by_another_thread() {
        let b = Budget::new(10);
        let held = b.try_take(10, "first").unwrap();
        let b2 = b.clone();
        let t = std::thread::spawn(move || {
            b2.take(5, "second", Duration::from_secs(30))
                .map(|l| l.bytes())
        });
        std::thread::sleep(Duration::from_millis(50));
        drop(held);
        assert_eq!(t.join().unwrap().unwrap(), 5);
    }
}
