//! Feature maps in the engine's layout: channels-last (`[h][w][c]`), optionally with a
//! one-pixel zero border so 3x3 convolutions read their neighbourhood without bounds checks,
//! and planar images (`[c][h][w]`, the layout of the network's input and output).

/// A planar `[channels][height][width]` tensor of one image.
#[derive(Clone, Debug, PartialEq)]
pub struct Planar {
    /// Channels.
    pub channels: usize,
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
    /// `channels * height * width` values, channel-major.
    pub data: Vec<f32>,
}

impl Planar {
    /// A zero tensor.
    #[must_use]
    pub fn zeros(channels: usize, height: usize, width: usize) -> Self {
        Self {
            channels,
            height,
            width,
            data: vec![0.0; channels * height * width],
        }
    }
}

/// A channels-last feature map with a zero border of `pad` pixels.
#[derive(Clone, Debug)]
pub(crate) struct Feature {
    pub h: usize,
    pub w: usize,
    pub c: usize,
    pub pad: usize,
    pub data: Vec<f32>,
}

impl Feature {
    /// A zero map of `h x w x c` with a border of `pad` pixels.
    pub fn zeros(h: usize, w: usize, c: usize, pad: usize) -> Self {
        Self {
            h,
            w,
            c,
            pad,
            data: vec![0.0; (h + 2 * pad) * (w + 2 * pad) * c],
        }
    }

    /// A map for an operation to write: storage from `pool` (no page faults and no zeroing
    /// pass once the pool is warm), the border zero, the interior holding stale values that
    /// the caller overwrites in full.
    pub fn output_in(pool: &mut Pool, h: usize, w: usize, c: usize, pad: usize) -> Self {
        let mut f = Self {
            h,
            w,
            c,
            pad,
            data: pool.take_stale((h + 2 * pad) * (w + 2 * pad) * c),
        };
        if pad > 0 {
            let stride = f.row_stride();
            let (top, rest) = f.data.split_at_mut(pad * stride);
            top.fill(0.0);
            let (mid, bottom) = rest.split_at_mut(h * stride);
            bottom.fill(0.0);
            for row in mid.chunks_exact_mut(stride) {
                row[..pad * c].fill(0.0);
                row[stride - pad * c..].fill(0.0);
            }
        }
        f
    }

    /// Floats between vertically adjacent pixels.
    pub fn row_stride(&self) -> usize {
        (self.w + 2 * self.pad) * self.c
    }

    /// Index of channel 0 of interior pixel `(y, x)`.
    pub fn at(&self, y: usize, x: usize) -> usize {
        (y + self.pad) * self.row_stride() + (x + self.pad) * self.c
    }

    /// The `c` values of interior row `y` (without the border).
    pub fn row(&self, y: usize) -> &[f32] {
        let i = self.at(y, 0);
        &self.data[i..i + self.w * self.c]
    }

    /// The `c` values of interior row `y`, mutable.
    pub fn row_mut(&mut self, y: usize) -> &mut [f32] {
        let i = self.at(y, 0);
        let n = self.w * self.c;
        &mut self.data[i..i + n]
    }

    /// Channels-last copy of a planar tensor.
    pub fn from_planar(p: &Planar, pad: usize) -> Self {
        let mut f = Self::zeros(p.height, p.width, p.channels, pad);
        let plane = p.height * p.width;
        for y in 0..p.height {
            let c = p.channels;
            let row = f.row_mut(y);
            for (x, px) in row.chunks_exact_mut(c).enumerate() {
                for (ch, v) in px.iter_mut().enumerate() {
                    *v = p.data[ch * plane + y * p.width + x];
                }
            }
        }
        f
    }

    /// Planar copy of the interior.
    pub fn to_planar(&self) -> Planar {
        let mut p = Planar::zeros(self.c, self.h, self.w);
        let plane = self.h * self.w;
        for y in 0..self.h {
            for (x, px) in self.row(y).chunks_exact(self.c).enumerate() {
                for (ch, &v) in px.iter().enumerate() {
                    p.data[ch * plane + y * self.w + x] = v;
                }
            }
        }
        p
    }
}

/// Buffers a [`Pool`] keeps at most.
const MAX_POOLED: usize = 32;
/// Bytes a [`Pool`] keeps at most between passes of one kind: more than every buffer of a
/// forward pass at the renderer's largest tile (1024x1024, the full-width network), so that
/// repeated passes (images of one size, a photo's equal tiles) reuse memory they have already
/// touched instead of faulting in fresh pages for every map.
const MAX_POOLED_BYTES: usize = 1 << 30;
/// Bytes kept when the kind of pass changes (another input size or encoder depth): the
/// buffers of the old kind fit the new one badly, and keeping them all would add one kind's
/// memory to the next's.
const KEPT_ACROSS_KINDS: usize = 64 << 20;
/// Fresh buffers at least this large are advised into transparent huge pages where the
/// system offers them on request (Linux `madvise`).
const HUGE_PAGE_MIN_BYTES: usize = 8 << 20;

/// What a pass is, for [`Pool::begin`]: its input's channels, height and width and how deep
/// it runs.
pub(crate) type PassKind = (usize, usize, usize, usize);

/// Buffers kept between forward passes, so that a render reuses memory it has already
/// touched instead of faulting in fresh pages for every feature map.
#[derive(Debug, Default)]
pub(crate) struct Pool {
    free: Vec<Vec<f32>>,
    /// The kind of the last pass.
    kind: Option<PassKind>,
}

impl Pool {
    /// Starts a pass of `kind`: where the last pass was of another kind, only
    /// [`KEPT_ACROSS_KINDS`] bytes of buffers are kept.
    pub fn begin(&mut self, kind: PassKind) {
        if self.kind != Some(kind) {
            self.trim(KEPT_ACROSS_KINDS);
            self.kind = Some(kind);
        }
    }

    /// A buffer of `n` floats, from the smallest free buffer that holds it, with whatever
    /// values it last held (zeros where it is new).
    pub fn take_stale(&mut self, n: usize) -> Vec<f32> {
        let best = self
            .free
            .iter()
            .enumerate()
            .filter(|(_, v)| v.capacity() >= n)
            .min_by_key(|(_, v)| v.capacity())
            .map(|(i, _)| i);
        match best {
            Some(i) => {
                let mut v = self.free.swap_remove(i);
                if v.len() >= n {
                    v.truncate(n);
                } else {
                    v.resize(n, 0.0);
                }
                v
            }
            None => fresh_zeros(n),
        }
    }

    /// Returns a feature map's storage.
    pub fn give(&mut self, f: Feature) {
        self.free.push(f.data);
    }

    /// Returns a buffer.
    pub fn give_vec(&mut self, v: Vec<f32>) {
        self.free.push(v);
    }

    /// Moves the buffers of `other` (a pass's pool) into this pool, which takes its kind,
    /// keeping at most [`MAX_POOLED`] buffers and [`MAX_POOLED_BYTES`], largest first.
    pub fn absorb(&mut self, other: Pool) {
        self.free.extend(other.free);
        self.kind = other.kind.or(self.kind);
        self.trim(MAX_POOLED_BYTES);
    }

    /// Keeps at most [`MAX_POOLED`] buffers and `bytes`, largest first.
    fn trim(&mut self, bytes: usize) {
        self.free.sort_by_key(|v| std::cmp::Reverse(v.capacity()));
        let mut kept = 0;
        self.free.retain(|v| {
            let b = v.capacity() * std::mem::size_of::<f32>();
            let keep = kept + b <= bytes;
            if keep {
                kept += b;
            }
            keep
        });
        self.free.truncate(MAX_POOLED);
    }
}

/// `n` zeros in memory the system zeroes as it is first touched (so by the threads that write
/// it, not in one pass here), advised into huge pages when large.
fn fresh_zeros(n: usize) -> Vec<f32> {
    let v = vec![0.0f32; n];
    advise_huge_pages(&v);
    v
}

/// Asks Linux to back the 2 MiB-aligned interior of `v` with transparent huge pages (fewer
/// page faults and TLB misses on maps of tens of megabytes). Advice only: nothing changes
/// where the system declines it.
#[cfg(target_os = "linux")]
fn advise_huge_pages(v: &[f32]) {
    const HUGE: usize = 2 << 20;
    let bytes = std::mem::size_of_val(v);
    if bytes < HUGE_PAGE_MIN_BYTES {
        return;
    }
    let start = (v.as_ptr() as usize).next_multiple_of(HUGE);
    let end = (v.as_ptr() as usize + bytes) / HUGE * HUGE;
    if end > start {
        // SAFETY: the range lies inside `v`'s own allocation; MADV_HUGEPAGE changes how its
        // pages are backed, never their contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_: &[f32]) {}

/// A pointer that may be shared between the threads writing disjoint parts of one buffer.
pub(crate) struct SharedMut<T = f32>(pub *mut T);
impl<T> SharedMut<T> {
    /// The pointer (a method, so closures capture the whole `Sync` wrapper).
    pub fn get(self) -> *mut T {
        self.0
    }
}

impl<T> Clone for SharedMut<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for SharedMut<T> {}

// SAFETY: users write disjoint ranges only (each parallel work item owns its output range).
unsafe impl<T> Send for SharedMut<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for SharedMut<T> {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planar_round_trip_keeps_the_border_zero() {
        let p = Planar {
            channels: 2,
            height: 2,
            width: 3,
            data: (0..12).map(|v| v as f32 + 1.0).collect(),
        };
        let f = Feature::from_planar(&p, 1);
        assert_eq!(f.data.len(), 4 * 5 * 2);
        assert_eq!(f.data[f.at(1, 2)], 6.0);
        assert_eq!(f.data[f.at(1, 2) + 1], 12.0);
        assert_eq!(f.data.iter().filter(|&&v| v == 0.0).count(), 40 - 12);
        assert_eq!(f.to_planar(), p);
    }

    #[test]
    fn the_pool_keeps_buffers_for_passes_of_one_kind_only() {
        const MB: usize = (1 << 20) / 4;
        let held = |p: &Pool| p.free.iter().map(Vec::capacity).sum::<usize>() / MB;
        let mut shared = Pool::default();
        let pass = |shared: &mut Pool, kind: PassKind, sizes: &[usize]| {
            let mut pool = std::mem::take(shared);
            pool.begin(kind);
            let bufs: Vec<Vec<f32>> = sizes.iter().map(|&n| pool.take_stale(n * MB)).collect();
            let caps: Vec<usize> = bufs.iter().map(|b| b.capacity() / MB).collect();
            for b in bufs {
                pool.give_vec(b);
            }
            shared.absorb(pool);
            caps
        };
        let big = (1, 1024, 1024, 4);
        assert_eq!(pass(&mut shared, big, &[96, 32, 48]), [96, 32, 48]);
        assert_eq!(held(&shared), 176, "a large pass's buffers are kept");
        // The same kind again takes the same buffers (the smallest that fits each request).
        assert_eq!(pass(&mut shared, big, &[32, 48, 96]), [32, 48, 96]);
        assert_eq!(held(&shared), 176);
        // Another kind keeps only 64 MB of them (the 48 MB buffer: the largest that fits),
        // lends it for the first request and allocates the second.
        let small = (1, 512, 512, 4);
        assert_eq!(pass(&mut shared, small, &[8, 40]), [48, 40]);
        assert_eq!(held(&shared), 88);
    }

    #[test]
    fn a_reused_buffer_gets_a_zero_border() {
        let mut pool = Pool::default();
        pool.give_vec(vec![7.0; 100]);
        let f = Feature::output_in(&mut pool, 3, 2, 2, 1);
        assert_eq!(f.data.len(), 5 * 4 * 2);
        for y in 0..5 {
            for x in 0..4 {
                let interior = (1..4).contains(&y) && (1..3).contains(&x);
                let v = f.data[(y * 4 + x) * 2];
                assert_eq!(v == 0.0, !interior, "({y}, {x}) = {v}");
            }
        }
    }
}
