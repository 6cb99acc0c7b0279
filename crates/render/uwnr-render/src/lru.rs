//! A small map that keeps the most recently used entries within a count and, when asked, a
//! number of bytes: the page's caches and a render job's prepared references. The order of use
//! is the `lru` crate's; the sizes and the byte bound are counted here.

use std::hash::Hash;

/// A small map that forgets its least recently used entries beyond a count or a byte total.
pub struct Lru<K: Hash + Eq, V> {
    cap: usize,
    max_bytes: u64,
    bytes: u64,
    /// Each value with its size in bytes.
    items: lru::LruCache<K, (V, u64)>,
}

impl<K: Hash + Eq, V: Clone> Lru<K, V> {
    /// A map of at most `cap` entries.
    #[must_use]
    pub fn new(cap: usize) -> Self {
        Self::with_bytes(cap, u64::MAX)
    }

    /// A map of at most `cap` entries whose sizes ([`Self::put_sized`]) add up to at most
    /// `max_bytes`; an entry larger than that alone is not kept.
    #[must_use]
    pub fn with_bytes(cap: usize, max_bytes: u64) -> Self {
        Self {
            cap,
            max_bytes,
            bytes: 0,
            items: lru::LruCache::unbounded(),
        }
    }

    /// The value of `k`, now the most recently used.
    pub fn get(&mut self, k: &K) -> Option<V> {
        self.items.get(k).map(|(v, _)| v.clone())
    }

    /// Sets `k` to `v` (size 0), the most recently used; the least recently used beyond the
    /// bounds go.
    pub fn put(&mut self, k: K, v: V) {
        self.put_sized(k, v, 0);
    }

    /// Sets `k` to `v` of `bytes`, the most recently used; the least recently used beyond the
    /// bounds go. Nothing is kept when `bytes` alone exceeds the byte bound.
    pub fn put_sized(&mut self, k: K, v: V, bytes: u64) {
        self.remove(&k);
        if bytes > self.max_bytes {
            return;
        }
        self.items.push(k, (v, bytes));
        self.bytes += bytes;
        self.shrink();
    }

    /// Sets the size of `k` (now known), without making it more recently used; entries beyond
    /// the bounds go, `k` itself when it alone exceeds the byte bound.
    pub fn set_size(&mut self, k: &K, bytes: u64) {
        if bytes > self.max_bytes {
            self.remove(k);
            return;
        }
        let Some((_, size)) = self.items.peek_mut(k) else {
            return;
        };
        let old = std::mem::replace(size, bytes);
        self.bytes = self.bytes - old + bytes;
        self.shrink();
    }

    /// Bytes of the entries kept.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Entries kept.
    #[must_use]
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether nothing is kept.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    fn remove(&mut self, k: &K) {
        if let Some((_, b)) = self.items.pop(k) {
            self.bytes -= b;
        }
    }

    fn shrink(&mut self) {
        while self.items.len() > self.cap || self.bytes > self.max_bytes {
            match self.items.pop_lru() {
                Some((_, (_, b))) => self.bytes -= b,
                None => break,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_recently_used_go_beyond_the_count() {
        let mut m = Lru::new(2);
        m.put("a", 1);
        m.put("b", 2);
        assert_eq!(m.get(&"a"), Some(1));
        m.put("c", 3);
        assert_eq!(m.get(&"b"), None);
        assert_eq!((m.get(&"a"), m.get(&"c")), (Some(1), Some(3)));
    }

    #[test]
    fn the_least_recently_used_go_beyond_the_bytes_and_a_huge_entry_is_not_kept() {
        let mut m = Lru::with_bytes(10, 100);
        m.put_sized("a", 1, 60);
        m.put_sized("b", 2, 30);
        assert_eq!(m.bytes(), 90);
        m.get(&"a");
        m.put_sized("c", 3, 30);
        // b was the least recently used: 60 + 30.
        assert_eq!((m.get(&"b"), m.bytes()), (None, 90));
        m.put_sized("huge", 4, 101);
        assert_eq!((m.get(&"huge"), m.len()), (None, 2));
        m.set_size(&"c", 50);
        assert_eq!((m.get(&"a"), m.bytes()), (None, 50));
        m.put_sized("c", 5, 10);
        assert_eq!((m.get(&"c"), m.bytes(), m.len()), (Some(5), 10, 1));
    }
}
