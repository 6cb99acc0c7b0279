//! Rendering a clean photo into an underwater image with the UWNR generator (Ye et al.,
//! CVPR-W 2022, Eq. 6: `x = G(concat[y, depth(y), LF(x_ref)])`), at any size.
//!
//! The network needs sizes that are multiples of 16 (four stride-2 levels). The input is
//! padded up by reflection, not zeros: a zero border is an edge the convolutions respond to and
//! it would bias the channel-attention means (the global average pools), while a mirrored
//! border continues the local statistics (reflect-101, as NumPy's `reflect`:
//! [`uwnr_core::index::reflect101`]). The output is cropped back and clamped to [0, 1].
//!
//! Large images are rendered in tiles. Everything in the network is local except channel
//! attention, which pools over the whole image; to keep that global, tiling runs in passes:
//! pass `k` (k = 0..4) runs every tile through the encoder up to block `k`, with the means of
//! blocks `< k` fixed from earlier passes, and sums block `k`'s channel-attention input over the
//! tile's core. Cores partition the padded image on a 16-pixel grid, so they partition every
//! level and each feature is counted once. The last pass renders every tile with all four
//! means fixed and blends neighbouring tiles with a linear ramp across their overlap.
//!
//! The output at a pixel depends on inputs at most [`RECEPTIVE_RADIUS`] pixels away. The ramp
//! between two tiles is kept that far from both tiles' cut edges when the overlap allows it
//! (overlap >= 2 x 76 + 32), in which case the blended tiles agree with the whole-image render
//! up to float rounding; with a smaller overlap the ramp spreads over the whole overlap and
//! hides, rather than removes, the seams.

use uwnr_core::Image;
use uwnr_core::index::reflect101;
use uwnr_core::lightfield::{LightFieldMap, light_field_for_with};
use uwnr_core::resize::{LazyResize, resize_bilinear};
use uwnr_engine::Planar;

use crate::config::{LEVELS, SIZE_MULTIPLE};
use crate::error::{ModelError, Result};
use crate::finish::{DepthResponse, finish, finish_uncorrected};
use crate::style::{ReferenceStyle, Variant, Water, anchor, water_anchor};

/// What tiled rendering needs of a generator implementation (the engine, or burn's module in
/// the training wing), on planar `[c][h][w]` tensors of one image.
pub trait Forward {
    /// Input and output channels.
    fn channels(&self) -> (usize, usize);
    /// The released forward pass.
    fn forward(&self, x: Planar) -> Result<Planar>;
    /// The forward pass with every block's channel attention driven by `means`.
    fn forward_with_means(&self, x: Planar, means: &[Vec<f32>]) -> Result<Planar>;
    /// Block `known.len()`'s channel-attention input, earlier blocks gated with `known`.
    fn attention_input(&self, x: Planar, known: &[Vec<f32>]) -> Result<Planar>;
}

impl Forward for uwnr_engine::Generator {
    fn channels(&self) -> (usize, usize) {
        (self.in_channels(), self.out_channels())
    }

    fn forward(&self, x: Planar) -> Result<Planar> {
        Ok(uwnr_engine::Generator::forward(self, &x, uwnr_engine::Means::Own)?.0)
    }

    fn forward_with_means(&self, x: Planar, means: &[Vec<f32>]) -> Result<Planar> {
        Ok(uwnr_engine::Generator::forward(self, &x, uwnr_engine::Means::Given(means))?.0)
    }

    fn attention_input(&self, x: Planar, known: &[Vec<f32>]) -> Result<Planar> {
        Ok(self.channel_attention_input(&x, known)?)
    }
}

/// Channels of the clean RGB image.
const CLEAN_CHANNELS: usize = 3;
/// Channels of the depth map.
const DEPTH_CHANNELS: usize = 1;
/// Channels of the light-field map.
const LIGHT_FIELD_CHANNELS: usize = 3;

/// Half-width, in input pixels, of the generator's receptive field: the encoder's convs add
/// 1+2 (level 1), 2+4, 4+8 and 8+16 (a stride-2 conv3x3 and the block's conv3x3 at spacings
/// 1, 2, 4, 8, 16), the decoder's conv3x3 16+8+4+2 and the output conv 1: 76 in all.
pub const RECEPTIVE_RADIUS: usize = 76;
/// Half-width of the encoder's receptive field up to the last block (45 px), rounded up to
/// the 16-pixel grid: the context the channel-mean passes need around each core.
const ENCODER_MARGIN: usize = 48;
/// Narrowest blending ramp kept when the overlap is too small to stay [`RECEPTIVE_RADIUS`]
/// away from both cut edges.
const MIN_RAMP: usize = 32;
/// Overlaps are multiples of this so that a tile, extending half the overlap beyond its core,
/// starts on the 16-pixel grid.
const OVERLAP_MULTIPLE: usize = 2 * SIZE_MULTIPLE;

/// When and how to tile, and how the anchored variant responds to depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Images whose padded size has more pixels than this are rendered in tiles; smaller ones
    /// in one pass. 0 forces tiling.
    pub max_tile_pixels: usize,
    /// Largest tile side in pixels (a multiple of 16, larger than `overlap`).
    pub tile: usize,
    /// Pixels shared by neighbouring tiles (a multiple of 32); half of it extends each tile
    /// beyond its core.
    pub overlap: usize,
    /// What the depth map's values stand for and how far its differences are trusted
    /// ([`crate::style`]; [`DepthResponse::for_depth`] for a `uwnr_depth::Depth`). The default
    /// is the built-in prior's: relative, the image's mean depth taken to be the reference's.
    /// The paper's variant reads depth as given either way.
    pub depth: DepthResponse,
}

impl Default for RenderOptions {
    /// Tiles of 1024 px (the whole image up to 1024 x 1024 px), overlapping by 192 px so the
    /// tiled render matches the whole-image render. Peak memory at full width is set by the
    /// tile size, not the image size.
    fn default() -> Self {
        Self {
            max_tile_pixels: 1024 * 1024,
            tile: 1024,
            overlap: 6 * OVERLAP_MULTIPLE,
            depth: DepthResponse::default(),
        }
    }
}

impl RenderOptions {
    /// Checks the tile geometry.
    pub fn validate(&self) -> Result<()> {
        if self.tile == 0 || !self.tile.is_multiple_of(SIZE_MULTIPLE) {
            return Err(ModelError::InvalidOptions(format!(
                "tile = {} must be a positive multiple of {SIZE_MULTIPLE}",
                self.tile
            )));
        }
        if !self.overlap.is_multiple_of(OVERLAP_MULTIPLE) {
            return Err(ModelError::InvalidOptions(format!(
                "overlap = {} must be a multiple of {OVERLAP_MULTIPLE}",
                self.overlap
            )));
        }
        if self.overlap + SIZE_MULTIPLE > self.tile {
            return Err(ModelError::InvalidOptions(format!(
                "tile = {} must exceed overlap = {} by at least {SIZE_MULTIPLE}",
                self.tile, self.overlap
            )));
        }
        Ok(())
    }
}

/// Renders `clean` (3 channels) as an underwater image in the style of a reference, using
/// `depth` (1 channel, the same size), on any implementation of the generator and any variant;
/// the style's light field is resized to the clean image's size. The output has the clean
/// image's size, values in [0, 1].
pub fn render_with(
    generator: &dyn Forward,
    variant: Variant,
    clean: &Image,
    depth: &Image,
    style: &ReferenceStyle,
    opts: &RenderOptions,
) -> Result<Image> {
    opts.validate()?;
    let (w, h) = clean.size();
    if w == 0 || h == 0 {
        return Err(uwnr_core::CoreError::Empty {
            width: w,
            height: h,
        }
        .into());
    }
    // The light field at the clean image's size, sampled tile by tile as the network needs it
    // rather than held whole (a 12 MP photo would hold 144 MB of it).
    let lf = LazyResize::new(light_field_of(style)?, w, h)?;
    for (what, size, channels, expected) in [
        (
            "clean image",
            clean.size(),
            clean.channels(),
            CLEAN_CHANNELS,
        ),
        ("depth map", depth.size(), depth.channels(), DEPTH_CHANNELS),
        (
            "light-field map",
            lf.size(),
            lf.channels(),
            LIGHT_FIELD_CHANNELS,
        ),
    ] {
        if channels != expected {
            return Err(ModelError::Channels {
                what,
                expected,
                got: channels,
            });
        }
        if size != clean.size() {
            return Err(ModelError::ImageSize {
                what,
                expected: clean.size(),
                got: size,
            });
        }
    }
    match variant {
        Variant::Paper => {
            let sources = [
                Source::Image(clean),
                Source::Image(depth),
                Source::Lazy(&lf),
            ];
            let mut out = run(generator, variant, &sources, opts)?;
            out.clamp01();
            Ok(out)
        }
        Variant::Anchored => {
            let (water, a) = anchored_start(clean, style)?;
            let sources = [Source::Image(clean), Source::Lazy(&lf), Source::Image(&a)];
            let raw = run(generator, variant, &sources, opts)?;
            finish(raw, a, depth, water, &opts.depth)
        }
    }
}

/// The anchored render of a model whose correction is none: the anchor through the depth
/// stage, no network.
pub(crate) fn render_uncorrected(
    clean: &Image,
    depth: &Image,
    style: &ReferenceStyle,
    opts: &RenderOptions,
) -> Result<Image> {
    let (water, a) = anchored_start(clean, style)?;
    finish_uncorrected(a, depth, water, &opts.depth)
}

/// The style's light field, which a network and the Reinhard anchor read.
fn light_field_of(style: &ReferenceStyle) -> Result<&Image> {
    style.light_field.as_ref().ok_or_else(|| {
        ModelError::InvalidOptions(
            "this model reads the reference's light field, and the style has none (made for a \
             model without a network)"
                .into(),
        )
    })
}

/// The reference's water and the anchor of `clean` (the water anchor's, or the Reinhard anchor
/// with light-field retention, which reads the whole map once at the image's size).
fn anchored_start<'s>(clean: &Image, style: &'s ReferenceStyle) -> Result<(&'s Water, Image)> {
    let (w, h) = clean.size();
    let water = style.water.as_ref().ok_or_else(|| {
        ModelError::InvalidOptions(
            "the anchored model needs the reference's water (ReferenceStyle::new)".into(),
        )
    })?;
    let a = if water.affine.is_some() {
        water_anchor(clean, water)?
    } else {
        let lf_full = resize_bilinear(light_field_of(style)?, w, h)?;
        anchor(clean, water, &lf_full, |im| {
            Ok(light_field_for_with(im, w, h, LightFieldMap::Absolute)?)
        })?
    };
    Ok((water, a))
}

/// The network's raw output for the stacked `sources` (whole image or tiled), unclamped.
fn run(
    generator: &dyn Forward,
    variant: Variant,
    sources: &[Source<'_>],
    opts: &RenderOptions,
) -> Result<Image> {
    let (cin, cout) = generator.channels();
    let (want_in, want_out) = variant.channels();
    let given: usize = sources.iter().map(Source::channels).sum();
    for (what, expected, got) in [
        ("generator input", want_in, cin),
        ("generator output", want_out, cout),
        ("network input planes", cin, given),
    ] {
        if expected != got {
            return Err(ModelError::Channels {
                what,
                expected,
                got,
            });
        }
    }
    let (w, h) = sources[0].size();
    let (hp, wp) = (padded(h), padded(w));
    if hp * wp <= opts.max_tile_pixels {
        let region = Rect {
            y0: 0,
            x0: 0,
            h: hp,
            w: wp,
        };
        let x = input_tensor(sources, region);
        let y = generator.forward(x)?.data; // [cout, hp, wp]
        crop_to_image(&y, cout, hp, wp, h, w)
    } else {
        render_tiled(generator, sources, (hp, wp), (h, w), opts)
    }
}

fn padded(n: usize) -> usize {
    n.div_ceil(SIZE_MULTIPLE) * SIZE_MULTIPLE
}

/// A rectangle of the padded image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    y0: usize,
    x0: usize,
    h: usize,
    w: usize,
}

/// One input of the network, at the clean image's size.
enum Source<'a> {
    /// Held whole.
    Image(&'a Image),
    /// A resize evaluated per tile.
    Lazy(&'a LazyResize<'a>),
}

impl Source<'_> {
    fn channels(&self) -> usize {
        match self {
            Self::Image(im) => im.channels(),
            Self::Lazy(r) => r.channels(),
        }
    }

    fn size(&self) -> (usize, usize) {
        match self {
            Self::Image(im) => im.size(),
            Self::Lazy(r) => r.size(),
        }
    }
}

/// The network input over `region` of the padded image: the sources' planes stacked,
/// `[channels, region.h, region.w]`.
fn input_tensor(sources: &[Source<'_>], region: Rect) -> Planar {
    let channels: usize = sources.iter().map(Source::channels).sum();
    let mut data = Vec::with_capacity(channels * region.h * region.w);
    for src in sources {
        let (w, h) = src.size();
        let cols: Vec<usize> = (region.x0..region.x0 + region.w)
            .map(|x| reflect101(x as i64, w))
            .collect();
        match src {
            Source::Image(im) => {
                for c in 0..im.channels() {
                    let plane = im.plane(c);
                    for y in region.y0..region.y0 + region.h {
                        let row = &plane[reflect101(y as i64, h) * w..][..w];
                        data.extend(cols.iter().map(|&x| row[x]));
                    }
                }
            }
            Source::Lazy(r) => {
                let rows: Vec<usize> = (region.y0..region.y0 + region.h)
                    .map(|y| reflect101(y as i64, h))
                    .collect();
                for c in 0..r.channels() {
                    r.sample(c, &rows, &cols, &mut data);
                }
            }
        }
    }
    Planar {
        channels,
        height: region.h,
        width: region.w,
        data,
    }
}

/// The top-left `h x w` of a `[channels, hp, wp]` output as an image.
fn crop_to_image(
    y: &[f32],
    channels: usize,
    hp: usize,
    wp: usize,
    h: usize,
    w: usize,
) -> Result<Image> {
    let mut data = Vec::with_capacity(channels * h * w);
    for c in 0..channels {
        for row in 0..h {
            data.extend_from_slice(&y[(c * hp + row) * wp..][..w]);
        }
    }
    Ok(Image::from_planar(w, h, channels, data)?)
}

/// Core boundaries along one axis of length `len` (a multiple of 16): `n + 1` multiples of 16
/// from 0 to `len`, with cores of at most `max_core` pixels, as equal as the grid allows.
fn core_bounds(len: usize, max_core: usize) -> Vec<usize> {
    let units = len / SIZE_MULTIPLE;
    let max_units = (max_core / SIZE_MULTIPLE).max(1);
    let n = units.div_ceil(max_units).max(1);
    (0..=n)
        .map(|i| (i * units).div_ceil(n) * SIZE_MULTIPLE)
        .collect()
}

/// Extent `[start, end)` of the tile around core `[b0, b1)`, extended by `margin` and clipped.
fn tile_extent(b0: usize, b1: usize, margin: usize, len: usize) -> (usize, usize) {
    (b0.saturating_sub(margin), (b1 + margin).min(len))
}

/// Blending weight along one axis of the tile around core `i` (bounds `b`), for the tile's
/// pixels `[start, end)`. Across the boundary `b[j]` between two tiles, the left tile's weight
/// falls and the right tile's rises linearly over `[b[j] - half + guard, b[j] + half - guard]`;
/// the two sum to 1.
fn axis_weights(
    b: &[usize],
    i: usize,
    start: usize,
    end: usize,
    half: usize,
    guard: usize,
) -> Vec<f32> {
    let ramp = |boundary: usize, p: usize, rising: bool| -> f32 {
        let lo = (boundary + guard) as f64 - half as f64;
        let hi = (boundary + half) as f64 - guard as f64;
        let x = p as f64 + 0.5;
        let t = if hi > lo {
            ((x - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else if x >= boundary as f64 {
            1.0
        } else {
            0.0
        };
        (if rising { t } else { 1.0 - t }) as f32
    };
    let last = b.len() - 2;
    (start..end)
        .map(|p| {
            let left = if i > 0 { ramp(b[i], p, true) } else { 1.0 };
            let right = if i < last {
                ramp(b[i + 1], p, false)
            } else {
                1.0
            };
            left * right
        })
        .collect()
}

fn render_tiled(
    generator: &dyn Forward,
    sources: &[Source<'_>],
    (hp, wp): (usize, usize),
    (h, w): (usize, usize),
    opts: &RenderOptions,
) -> Result<Image> {
    let half = opts.overlap / 2;
    let max_core = opts.tile - opts.overlap;
    let by = core_bounds(hp, max_core);
    let bx = core_bounds(wp, max_core);
    let cores = || (0..by.len() - 1).flat_map(|i| (0..bx.len() - 1).map(move |j| (i, j)));

    // Passes 0..LEVELS: the global mean of each block's channel-attention input.
    let enc_margin = half.min(ENCODER_MARGIN);
    let mut means: Vec<Vec<f32>> = Vec::with_capacity(LEVELS);
    for level in 0..LEVELS {
        let scale = 1 << (level + 1);
        let mut sum: Vec<f64> = Vec::new();
        for (i, j) in cores() {
            let (y0, y1) = tile_extent(by[i], by[i + 1], enc_margin, hp);
            let (x0, x1) = tile_extent(bx[j], bx[j + 1], enc_margin, wp);
            let region = Rect {
                y0,
                x0,
                h: y1 - y0,
                w: x1 - x0,
            };
            let x = input_tensor(sources, region);
            let a = generator.attention_input(x, &means)?; // [c, h/s, w/s]
            if sum.is_empty() {
                sum = vec![0.0; a.channels];
            }
            let (ry, rx) = (
                (by[i] - y0) / scale..(by[i + 1] - y0) / scale,
                (bx[j] - x0) / scale..(bx[j + 1] - x0) / scale,
            );
            let plane = a.height * a.width;
            for (s, p) in sum.iter_mut().zip(a.data.chunks_exact(plane)) {
                // Summed in f32 per row as burn's sum_dim did, then accumulated in f64.
                for y in ry.clone() {
                    let row: f32 = p[y * a.width..][rx.clone()].iter().sum();
                    *s += f64::from(row);
                }
            }
        }
        let count = ((hp / scale) * (wp / scale)) as f64;
        means.push(sum.into_iter().map(|s| (s / count) as f32).collect());
    }

    // Final pass: render each tile with the global means and blend.
    let guard = RECEPTIVE_RADIUS.min(opts.overlap.saturating_sub(MIN_RAMP) / 2);
    let cout = generator.channels().1;
    let mut acc = vec![0.0f32; cout * h * w];
    // The tiles form a grid and each one's weight is a product of a row and a column ramp, so
    // a pixel's total weight is (sum of the row ramps over it) x (sum of the column ramps):
    // two vectors instead of a plane.
    let mut weight_y = vec![0.0f32; h];
    let mut weight_x = vec![0.0f32; w];
    for (i, j) in cores() {
        let (y0, y1) = tile_extent(by[i], by[i + 1], half, hp);
        let (x0, x1) = tile_extent(bx[j], bx[j + 1], half, wp);
        // Rows and columns past the image are padding: no need to keep them.
        if y0 >= h || x0 >= w {
            continue;
        }
        let region = Rect {
            y0,
            x0,
            h: y1 - y0,
            w: x1 - x0,
        };
        let x = input_tensor(sources, region);
        let y = generator.forward_with_means(x, &means)?.data;
        let wy = axis_weights(&by, i, y0, y1, half, guard);
        let wx = axis_weights(&bx, j, x0, x1, half, guard);
        if j == 0 {
            for (ty, &wyv) in wy.iter().enumerate().take(h.min(y1) - y0) {
                weight_y[y0 + ty] += wyv;
            }
        }
        if i == 0 {
            for (tx, &wxv) in wx.iter().enumerate().take(w.min(x1) - x0) {
                weight_x[x0 + tx] += wxv;
            }
        }
        for (ty, &wyv) in wy.iter().enumerate().take(h.min(y1) - y0) {
            let row = y0 + ty;
            for (tx, &wxv) in wx.iter().enumerate().take(w.min(x1) - x0) {
                let wt = wyv * wxv;
                if wt == 0.0 {
                    continue;
                }
                let col = x0 + tx;
                for c in 0..cout {
                    acc[(c * h + row) * w + col] += wt * y[(c * region.h + ty) * region.w + tx];
                }
            }
        }
    }
    for c in 0..cout {
        for (row, wyv) in acc[c * h * w..(c + 1) * h * w]
            .chunks_exact_mut(w)
            .zip(&weight_y)
        {
            for (a, wxv) in row.iter_mut().zip(&weight_x) {
                // Every pixel lies in the core of some tile, where that tile's weight is >= 1/16.
                *a /= wyv * wxv;
            }
        }
    }
    Ok(Image::from_planar(w, h, cout, acc)?)
}

#[cfg(test)]
mod tests;
