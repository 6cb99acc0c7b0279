//! A small map that keeps the most recently used entries within a count: the page's caches and a
//! render job's prepared references.

use std::collections::VecDeque;

/// A small map that forgets its oldest entries beyond a count.
pub struct Lru<K, V> {
    cap: usize,
    items: VecDeque<(K, V)>,
}

impl<K: PartialEq, V: Clone> Lru<K, V> {
    /// A map of at most `cap` entries.
    #[must_use]
    pub fn new(cap: usize) -> Self {
        Self {
            cap,
            items: VecDeque::new(),
        }
    }

    /// The value of `k`, now the most recently used.
    pub fn get(&mut self, k: &K) -> Option<V> {
        let i = self.items.iter().position(|(x, _)| x == k)?;
        let item = self.items.remove(i)?;
        let v = item.1.clone();
        self.items.push_back(item);
        Some(v)
    }

    /// Sets `k` to `v`, the most recently used; the least recently used beyond the count go.
    pub fn put(&mut self, k: K, v: V) {
        self.items.retain(|(x, _)| x != &k);
        self.items.push_back((k, v));
        while self.items.len() > self.cap {
            self.items.pop_front();
        }
    }
}
