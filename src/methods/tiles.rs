//! Tiling (issue #14): an image too large for one chain — a binding over
//! `maxStorageBufferRange`, or device memory over the cap — is denoised in
//! tiles. Each tile is run as an image of its own, *with its halo*: the
//! pixels of the whole image within [`halo`] of the tile, so that every
//! output pixel of the tile's interior sees exactly the inputs it sees in an
//! untiled run, and is computed by the same arithmetic in the same order.
//! The interiors are pasted together; the output is **bit-identical** to the
//! untiled run on the same device (tested in `tests/tiles.rs`).
//!
//! Four things depend on where a tile lies in the image, or on the whole
//! image, not only on its pixels, and are carried over:
//! - LP's candidate grids (§3.5, `px mod g = 0`): the tile's grid phase
//!   ([`crate::shared::LpPush::phase_for`], from the tile's origin, [`Tile::placement`]);
//! - APR's sparse centres every 14 pixels (§4.3), and the 32-pixel spans
//!   ([`crate::kernels::box_rows::SPAN`], [`crate::kernels::outlier_spread::SPAN`])
//!   over which the outlier redistribution restarts its running box sums:
//!   the tile's first column and row are multiples of both ([`alignment`]),
//!   so its grids and spans are the image's;
//! - the sanitation counters (§0.4): a tile counts the repairs of its
//!   interior only ([`Tile::placement`]'s margins), so the report counts each pixel once;
//! - APR's mean sample count (APR-COUNT-CAP): the tile driver counts the
//!   whole image's samples on the host ([`ImageTotals::of`]) and every
//!   tile's APR takes those words instead of counting its own.
//!
//! What is global by nature, the sample map's allocation (§9.2: the sum of
//! the priorities, their prefix sum), runs once, untiled, on the priority
//! map the tiles computed ([`super::sampling::record_allocation`]).
//!
//! ## The halo, from the chain of windows
//!
//! A pixel's output depends on the inputs within a distance (in the
//! `|·|_inf` norm) that adds up along the chain, from the last stage back to
//! the input (spec sections in brackets):
//!
//! | stage | adds | why |
//! |---|---|---|
//! | sample map priority, MAP-SMOOTH (§9.1) | `ceil(3 σs)`: WLR and LP 3, APR 12, AOS 6, none 0 | `G_σs(r)` |
//! | outlier redistribution (§4.4 step 4) | 86 | `ŷ_final(i)` sums `ρ_o` over `o ∈ Ω_i(43)`, and `ρ_o` sums `ŷ` over `Ω_o(43)` |
//! | WLR (§2.3) | `R + 3`: 12 final, 8 intermediate | fits over `Ω_c(R)`; `hbar = G_1(h_opt)` (3) |
//! | LP (§3.5) | `9·(P + 1)` = 54 | pass `t`'s centres depend on the reach of the centres of earlier passes within 9, each fitted over its 19×19 window: `9(t + 1)` for `t < P = 5`; the gather reads the centres within 9 |
//! | APR (§4.3) | `14 + 28 T + 9` = 79 (T = 2 stages) | a stage's block at `c` reads the previous stage's blend within 14, which reads blocks within 14; the final blend reads blocks within 14; APR-VIS's filtered visibility reads the input within 9 (3×3 mean 1, NL-means search 5 + patch 3) |
//! | AOS (§5) | `R + 8`: 17 final, 13 intermediate | NL-means search 5 + patch 3, then the window `Ω_c(R)` |
//! | input blend (INPUT-BLEND), with the method | `max(method + s, r)` | reads the statistics the method read within its variance window `r` (AOS 1, the others 3), and the method's output within its residual window `s` (3, BLEND-RESIDUAL) |
//! | G-buffer prefilter (§6.2) | 24 (LP: 16) | `S̄ = G_1.5(S)` (5); SURE at `c` uses `S̃` within 3; `hbar = G_1.5(h_opt)` (5); GBF-SECOND's second pass reads the first's output within 3; GBF-NLM's albedo NL-means (not LP's by default) reads the prefilter's output within search 5 + patch 3 |
//! | outlier detection and replacement (§4.4 steps 1–3) | `14 (1 + rounds)` = 42 | `m_o`, `sd_o` and the median over `Ω_o(14)`; each OUTLIER-CLIP round keeps a pixel by what the round before kept within 14 |
//! | sanitation (§0.4) | 5 | step 1: 3×3 (1); then step 3 (5×5: 2) or step 4 (3×3 residuals, 7×7 MAD: 4) |
//!
//! With the pyramid's low band (PYRAMID-LOWBAND) the stages between the
//! sample map and the input, `H` in all (without the input blend's reach
//! beyond the method's: the coarse chain runs no blend), count twice, plus
//! 8: the merge reads the coarse outputs within one coarse pixel (2 fine
//! ones, and the block's second column: 3), which read the coarse inputs
//! within `H` coarse pixels, pooled from the fine statistics after
//! sanitation (5); and the fine level within 3, if that reaches further. The
//! tile's origin is then a multiple of twice the alignment, so the coarse
//! level's grids and 2×2 blocks are the whole image's.
//!
//! With the defaults (final pass, outlier stage on, prefilter where `auto`
//! runs it, the input blend after every method but `auto`): WLR 175, LP
//! 209, APR 251, AOS 159 (no prefilter by default, AOS-NO-GBF; 183 with
//! `--prefilter gbf`), and `none` 5 (it runs no
//! outlier stage and no prefilter by default). [`halo`] computes it for any configuration.
//!
//! Tiles run without OUTLIER-WIDE (`outliers.wide=0` whatever the
//! options say): its second spread reads the first's output within 215 px
//! of each outlier it weighs, which would add 2·215 px to every halo (APR
//! 251 → 681). A tiled run is bit-identical to a whole run with
//! `outliers.wide=0`, and differs from a whole run with the default where
//! an outlier goes wide.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::gpu::{DeviceInfo, GpuContext, KernelTiming, PlaneSet};
use crate::image::{crop_plane, Layer, RgbImage, StatsImage};
use crate::kernels::gauss_smooth;
use crate::reference;

use super::chain::{prefilter_runs, ChainConfig, ChainInput, GpuChain, ImageTotals, Placement};
use super::sampling::{self, SamplingParams, SamplingPlanes};
use super::{prepare, DenoiseOutput, Method, ProgressCallback, Tally};

/// A rectangle of pixels `[x0, x1) × [y0, y1)`.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Rect {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// One past the last column.
    pub x1: usize,
    /// One past the last row.
    pub y1: usize,
}

impl Rect {
    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.x1 - self.x0
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.y1 - self.y0
    }

    /// Pixels.
    pub fn pixels(&self) -> usize {
        self.width() * self.height()
    }
}

/// One tile: the interior it outputs, and the part of the image it reads
/// (the interior and its halo, clipped to the image).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Tile {
    /// The pixels this tile outputs, in image coordinates.
    pub inner: Rect,
    /// The pixels it reads, in image coordinates.
    pub outer: Rect,
}

impl Tile {
    /// The interior in the tile's own coordinates.
    pub fn inner_local(&self) -> Rect {
        Rect {
            x0: self.inner.x0 - self.outer.x0,
            y0: self.inner.y0 - self.outer.y0,
            x1: self.inner.x1 - self.outer.x0,
            y1: self.inner.y1 - self.outer.y0,
        }
    }

    /// Where the tile's chain lies in the image, and the margins whose
    /// sanitation repairs other tiles count.
    /// `totals`: the whole image's ([`ImageTotals::of`]).
    pub fn placement(&self, totals: ImageTotals) -> Placement {
        let l = self.inner_local();
        let (w, h) = (self.outer.width(), self.outer.height());
        let pack = |a: usize, b: usize| (a as u32) | (b as u32) << 16;
        Placement {
            origin: (self.outer.x0 as u32, self.outer.y0 as u32),
            skip: [pack(l.x0, l.y0), pack(w - l.x1, h - l.y1)],
            totals: Some(totals),
        }
    }
}

/// The halo of a configuration, stage by stage (see the module table).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Halo {
    /// `(stage, pixels)` from the last stage back to the input.
    pub parts: Vec<(&'static str, usize)>,
}

impl Halo {
    /// The whole halo in pixels.
    pub fn total(&self) -> usize {
        self.parts.iter().map(|(_, p)| p).sum()
    }
}

/// The halo of `config` on an input that the G-buffer prefilter runs on
/// when `prefiltered` (see the module documentation for the derivation).
pub fn halo(config: &ChainConfig, prefiltered: bool) -> Result<Halo> {
    let mut parts = Vec::new();
    let sampling = SamplingParams::with_options(config.method, &config.options)?;
    if sampling.sigma_s > 0.0 {
        parts.push((
            "sample map smoothing (§9.1)",
            gauss_smooth::radius(sampling.sigma_s) as usize,
        ));
    }
    let detect = reference::outliers::DETECT_RADIUS;
    if config.outliers {
        // A spread reads ŷ within its radius R of each outlier within R:
        // 2R. Tiles run without OUTLIER-WIDE ([`TiledChain::choose`]).
        let spread = reference::outliers::SPREAD_RADIUS;
        parts.push(("outlier redistribution (§4.4 step 4)", 2 * spread));
    }
    let method = (config.method.info().halo)(config)?;
    // The input blend reads the statistics the method read within its
    // variance window of the pixel, and the method's output (and the
    // statistics) within its residual window (BLEND-RESIDUAL).
    let with_blend = if config.input_blend {
        let b = super::blend::params(config.method, &config.options)?;
        (method + b.residual_radius as usize).max(b.reach())
    } else {
        method
    };
    parts.push(("method (and the input blend)", with_blend));
    if prefiltered {
        let s = gauss_smooth::radius(reference::gbf::SMOOTH_SIGMA) as usize;
        // GBF-SECOND's pass reads the first pass's output within the
        // filter's window, GBF-NLM's the last pass's within its search and
        // patch radii.
        let extra =
            super::gbf::GbfSettings::new(&config.options, config.method, config.pass)?.extra_halo();
        parts.push((
            "G-buffer prefilter (§6.2, GBF-SECOND, GBF-NLM)",
            2 * s + reference::gbf::RADIUS + extra,
        ));
    }
    if config.outliers {
        // OUTLIER-CLIP: round r keeps a pixel by the pixels within R that
        // round r - 1 kept, so the kept set after the rounds reads R more
        // per round.
        let rounds = super::outliers::clip_rounds(&config.options)? as usize;
        parts.push((
            "outlier detection (§4.4 steps 1-3, OUTLIER-CLIP)",
            detect * (1 + rounds),
        ));
    }
    parts.push(("sanitation (§0.4)", SANITIZE_HALO));
    if config.pyramid {
        // The merge reads the fine level within 3 (its chain's halo `F`)
        // and the coarse level's outputs within 1 coarse pixel, each made
        // from coarse inputs within the coarse chain's halo `H`, pooled
        // from the sanitised fine statistics: 2 (H + 1) + 1 + 5 fine
        // pixels, or 3 + F if more. The coarse chain runs no input blend:
        // `H` is `F` without the blend's reach beyond the method's.
        let keep = usize::from(sampling.sigma_s > 0.0);
        let fine: usize = parts[keep..].iter().map(|(_, p)| p).sum();
        let coarse = fine - (with_blend - method);
        parts.truncate(keep);
        parts.push(("pyramid merge (bilinear) and pooling", 3 + SANITIZE_HALO));
        parts.push((
            "pyramid coarse level (twice its chain's), or the fine level",
            (2 * coarse).max(fine.saturating_sub(SANITIZE_HALO)),
        ));
    }
    Ok(Halo { parts })
}

/// The sanitation's reach (§0.4): step 1's 3×3 median, then step 3's 5×5 or
/// step 4's 7×7 MAD of 3×3 residuals on its output.
pub const SANITIZE_HALO: usize = 5;

/// The multiple of which a tile's first column and row must be, so that
/// what depends on the position in the image stays as in a whole run:
/// the method's grid ([`super::MethodInfo::align`]: APR's centre spacing,
/// 14, §4.3), and with the outlier stage the
/// spans of 32 pixels over which `box_rows` (along x) and `outlier_spread`
/// (along y) restart their running sums (exact pairs, but their last
/// rounding depends on the sequence, which must be the same): the least
/// common multiple, or 1.
pub fn alignment(config: &ChainConfig) -> usize {
    // The pyramid's coarse level has the same grids at half the position:
    // a tile starts at twice their multiple, and on an even pixel (its 2×2
    // blocks are the image's).
    let pyramid = if config.pyramid { 2 } else { 1 };
    let grid = pyramid * config.method.info().align;
    let spans = if config.outliers {
        let (a, b) = (
            crate::kernels::box_rows::SPAN as usize,
            crate::kernels::outlier_spread::SPAN as usize,
        );
        pyramid * lcm(a, b)
    } else {
        pyramid
    };
    lcm(grid, spans)
}

fn lcm(a: usize, b: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    a / gcd(a, b) * b
}

/// Tiles of interior at most `tile × tile` pixels covering a `width ×
/// height` image, each with `halo` pixels around it (clipped to the image;
/// the outer rectangle starts at a multiple of `align`). Tiles of one row
/// or column share their interior size (the last may be smaller), so few
/// distinct outer sizes occur. Raster order.
pub fn plan(width: usize, height: usize, tile: usize, halo: usize, align: usize) -> Vec<Tile> {
    let align = align.max(1);
    let split = |n: usize| -> Vec<(usize, usize)> {
        let count = n.div_ceil(tile.max(1)).max(1);
        let size = n.div_ceil(count).div_ceil(align) * align;
        (0..n)
            .step_by(size)
            .map(|a| (a, (a + size).min(n)))
            .collect()
    };
    let (xs, ys) = (split(width), split(height));
    let mut tiles = Vec::with_capacity(xs.len() * ys.len());
    for &(y0, y1) in &ys {
        for &(x0, x1) in &xs {
            let lo = |a: usize| a.saturating_sub(halo) / align * align;
            tiles.push(Tile {
                inner: Rect { x0, y0, x1, y1 },
                outer: Rect {
                    x0: lo(x0),
                    y0: lo(y0),
                    x1: (x1 + halo).min(width),
                    y1: (y1 + halo).min(height),
                },
            });
        }
    }
    tiles
}

/// Images of at most this many pixels (512²) run whole without measuring
/// the chain's memory, unless a cap is given: ≈ 300 MB with the largest
/// configuration.
pub const SMALL: usize = 512 * 512;

/// The smallest tile interior (pixels per side) [`TiledChain::choose`] accepts
/// when it has to choose one: smaller tiles would spend almost all their
/// work on the halo.
pub const MIN_TILE: usize = 16;

/// Device memory of a `w × h` chain, `fixed + per_pixel · w·h` bytes plus
/// its rings of rows ([`GpuChain::ring_bytes`], known exactly), measured by
/// allocating two small chains of the same configuration.
#[derive(Clone, Debug)]
pub struct ChainMemory {
    /// Bytes that do not grow with the image.
    pub fixed: f64,
    /// Bytes per pixel.
    pub per_pixel: f64,
    /// The configuration, for the rings.
    config: ChainConfig,
}

impl ChainMemory {
    /// Measures the chain of `config` on inputs with `layers`.
    pub fn measure(
        ctx: &Arc<GpuContext>,
        layers: &[Layer],
        config: &ChainConfig,
    ) -> Result<ChainMemory> {
        // Without the rings: at these sizes a ring covers the whole height,
        // so it would be charged per pixel.
        let bytes = |side: usize| -> Result<f64> {
            let before = ctx.allocated_bytes();
            let input = ChainInput::Stats {
                width: side,
                height: side,
                layers: layers.to_vec(),
            };
            let chain = GpuChain::new(ctx, input, config.clone())?;
            let b = ctx.allocated_bytes().saturating_sub(before);
            drop(chain);
            Ok(b as f64 - GpuChain::ring_bytes(config, side, side) as f64)
        };
        let (a, b) = (bytes(64)?, bytes(128)?);
        let per_pixel = ((b - a) / (128.0 * 128.0 - 64.0 * 64.0)).max(0.0);
        Ok(ChainMemory {
            fixed: (a - per_pixel * 64.0 * 64.0).max(0.0),
            per_pixel,
            config: config.clone(),
        })
    }

    /// Bytes of a `width × height` chain.
    pub fn bytes(&self, width: usize, height: usize) -> f64 {
        self.fixed
            + self.per_pixel * (width * height) as f64
            + GpuChain::ring_bytes(&self.config, width, height) as f64
    }
}

/// Device memory the untiled part of a tiled run holds for a `pixels`-pixel
/// image, which may be asked for a sample map (every device makes one): the
/// priority and sample-count planes, the spp plane, and the allocation's
/// trees (§9.2).
pub fn global_bytes(pixels: usize) -> f64 {
    // 4 f32 planes of the sampling maps, the u32 counts, the spp plane, and
    // the trees (< 3 × 8 bytes × pixels/63 + levels).
    pixels as f64 * (4.0 * 4.0 + 4.0 + 4.0 + 0.5)
}

/// The memory cap when none is given: three quarters of the largest
/// device-local heap (on lavapipe, of host memory), so that the host keeps
/// room for the image itself.
pub fn default_cap(device: &DeviceInfo) -> u64 {
    device.device_local_heap / 4 * 3
}

/// The GPU chain of a configuration for an image of any size: tiles with
/// their halos ([`plan`]), one [`GpuChain`] per distinct tile size, made
/// when it is needed and dropped after its tiles, so the device holds one at
/// a time; the sample map's allocation untiled.
pub struct TiledChain {
    ctx: Arc<GpuContext>,
    width: usize,
    height: usize,
    layers: Vec<Layer>,
    config: ChainConfig,
    halo: Halo,
    tiles: Vec<Tile>,
}

impl std::fmt::Debug for TiledChain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TiledChain")
            .field("size", &(self.width, self.height))
            .field("halo", &self.halo.total())
            .field("tiles", &self.tiles.len())
            .finish()
    }
}

/// What [`TiledChain::choose`] decided.
pub enum Choice {
    /// The whole image fits one chain.
    Whole(Box<GpuChain>),
    /// Tiles.
    Tiled(Box<TiledChain>),
}

impl TiledChain {
    /// One chain for the whole `input` when it fits — every binding within
    /// `maxStorageBufferRange`, its device memory within `max_memory` bytes
    /// (default [`default_cap`]) — and `tile` is `None`; else tiles of at
    /// most `tile` pixels per side (or the largest that fit the cap and the
    /// bindings). Tiling reads statistics in host memory: an
    /// [`ChainInput::Accum`] input that does not fit is an error (and only
    /// an explicit `max_memory` is checked for it).
    pub fn choose(
        ctx: &Arc<GpuContext>,
        input: ChainInput,
        config: ChainConfig,
        max_memory: Option<u64>,
        tile: Option<usize>,
    ) -> Result<Choice> {
        let (w, h) = input.size();
        let layers = input.layers();
        let accum = matches!(input, ChainInput::Accum(_));
        if tile.is_none() && max_memory.is_none() && (w * h <= SMALL || accum) {
            // Small enough for any device (no need to measure), or a
            // renderer's accumulation planes, which cannot be tiled: only an
            // explicit cap is checked for them.
            return Ok(Choice::Whole(Box::new(GpuChain::new(ctx, input, config)?)));
        }
        let cap = max_memory.unwrap_or_else(|| default_cap(ctx.info())) as f64;
        let mem = ChainMemory::measure(ctx, &layers, &config)?;
        let whole_fits = mem.bytes(w, h) <= cap;
        if tile.is_none() && whole_fits {
            match GpuChain::new(ctx, input.clone(), config.clone()) {
                Ok(c) => return Ok(Choice::Whole(Box::new(c))),
                Err(Error::Limit(_)) => {}
                Err(e) => return Err(e),
            }
        }
        let why = if whole_fits {
            "a binding would exceed maxStorageBufferRange".to_string()
        } else {
            format!(
                "its chain needs ≈ {} MB of device memory, over the cap of {} MB",
                (mem.bytes(w, h) / 1e6).ceil(),
                (cap / 1e6).floor()
            )
        };
        if config.coarse_map {
            return Err(Error::Limit(format!(
                "{w}x{h} with a coarse sample map (MAP-COARSE): its chain makes the whole image's map and \
                 cannot run in tiles ({})",
                if tile.is_some() {
                    "tiles were asked for".to_string()
                } else {
                    why.clone()
                }
            )));
        }
        if config.temporal != super::Temporal::Off {
            return Err(Error::Limit(format!(
                "{w}x{h} with the temporal filter: it keeps one state for the whole image and \
                 cannot run in tiles ({})",
                if tile.is_some() {
                    "tiles were asked for".to_string()
                } else {
                    why
                }
            )));
        }
        let layers = match &input {
            ChainInput::Stats { layers, .. } => layers.clone(),
            ChainInput::Accum(_) if tile.is_some() => {
                return Err(Error::InvalidArgument(
                    "tiling reads statistics in host memory (Source::Stats), not accumulation planes"
                        .into(),
                ))
            }
            ChainInput::Accum(_) => {
                return Err(Error::Limit(format!(
                    "a {w}x{h} accumulation source does not fit one chain ({why}); tiling needs the statistics in host memory (Source::Stats and Denoiser::denoise)"
                )))
            }
        };
        // OUTLIER-WIDE's second spread (R = 215) would add 2·215 px to every
        // halo: tiles spread as the spec does.
        let mut config = config;
        config.options = super::outliers::one_window(&config.options)?;
        let prefiltered = prefilter_runs(config.method, config.prefilter, &layers)?;
        let halo = halo(&config, prefiltered)?;
        let hl = halo.total();
        let align = alignment(&config);
        let global = global_bytes(w * h);
        let mut side = match tile {
            Some(0) => {
                return Err(Error::InvalidArgument(
                    "the tile size must be at least 1".into(),
                ))
            }
            Some(t) => t,
            None => {
                // The largest interior whose tile (clipped to the image)
                // fits the cap.
                let outer = |s: usize| ((s + 2 * hl + align).min(w), (s + 2 * hl + align).min(h));
                let fits = |s: usize| {
                    let (ow, oh) = outer(s);
                    mem.bytes(ow, oh) + global <= cap
                };
                if !fits(MIN_TILE) {
                    return Err(Error::Limit(format!(
                        "{w}x{h} with {}: {why}, and a tile of {MIN_TILE}² pixels with its halo of {hl} needs ≈ {} MB: raise the memory cap",
                        config.method.name(),
                        ((mem.bytes(outer(MIN_TILE).0, outer(MIN_TILE).1) + global) / 1e6).ceil()
                    )));
                }
                let (mut lo, mut hi) = (MIN_TILE, w.max(h));
                while lo < hi {
                    let mid = (lo + hi).div_ceil(2);
                    if fits(mid) {
                        lo = mid;
                    } else {
                        hi = mid - 1;
                    }
                }
                lo
            }
        };
        // Shrink until the largest tile's chain fits every binding.
        loop {
            let tiles = plan(w, h, side, hl, align);
            let big = tiles
                .iter()
                .map(|t| (t.outer.width(), t.outer.height()))
                .max_by_key(|&(a, b)| a * b)
                .unwrap_or((1, 1));
            let probe = ChainInput::Stats {
                width: big.0,
                height: big.1,
                layers: layers.clone(),
            };
            match GpuChain::new(ctx, probe, config.clone()) {
                Ok(_) => {
                    return Ok(Choice::Tiled(Box::new(TiledChain {
                        ctx: ctx.clone(),
                        width: w,
                        height: h,
                        layers,
                        config,
                        halo,
                        tiles,
                    })))
                }
                Err(Error::Limit(m)) if side > 1 && tile.is_none() => {
                    log::debug!("tile of {side} px: {m}; trying a smaller one");
                    side = (side * 3 / 4).max(1);
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// The tiles, raster order.
    pub fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// The halo.
    pub fn halo(&self) -> &Halo {
        &self.halo
    }

    /// `(width, height)` of the whole image.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The configuration.
    pub fn config(&self) -> &ChainConfig {
        &self.config
    }

    /// The statistics layers the tiles read.
    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }

    /// Denoises `img` tile by tile; with a `budget`, the sample map of §9
    /// over the whole image. `progress` gets the fraction of tiles done.
    pub fn denoise(
        &self,
        img: &StatsImage,
        budget: Option<u32>,
        statistics: bool,
        batch_progress: bool,
        progress: Option<&ProgressCallback>,
    ) -> Result<(DenoiseOutput, Option<StatsImage>)> {
        let (w, h) = (self.width, self.height);
        let layers: Vec<Layer> = img.layers().map(|(l, _)| l).collect();
        if (img.width, img.height) != (w, h) || layers != self.layers {
            return Err(Error::InvalidArgument(format!(
                "this denoiser was made for {w}x{h} statistics with {:?}; the image is {}x{} with {:?}",
                self.layers, img.width, img.height, layers
            )));
        }
        let n = w * h;
        let want_error = self.config.error;
        let mut color = RgbImage::new(w, h);
        let mut error = if want_error {
            RgbImage::new(w, h)
        } else {
            RgbImage::new(0, 0)
        };
        // The local dimension comes with the error estimate (chain.rs).
        let mut dim = vec![0.0f32; if want_error { n } else { 0 }];
        let mut priority = budget.map(|_| vec![0.0f32; n]);
        let mut debug_planes: Vec<(String, Vec<f32>)> = Vec::new();
        let mut report = prepare::base_report(img);
        let mut timings: Vec<KernelTiming> = Vec::new();
        // The run's statistics (LP's census): the tiles' sums and pixels.
        let mut sums: Vec<Tally> = Vec::new();
        // The sanitised (and prefiltered) statistics of every tile's interior.
        let mut clean: Option<StatsImage> = None;
        // Group the tiles by outer size: one chain per size, one at a time.
        let mut groups: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
        for (i, t) in self.tiles.iter().enumerate() {
            groups
                .entry((t.outer.width(), t.outer.height()))
                .or_default()
                .push(i);
        }
        // What is global to the image and some stage needs (APR-COUNT-CAP).
        let spp = img
            .get(Layer::Spp)
            .ok_or_else(|| Error::BadData("the statistics have no spp layer".into()))?;
        let totals = ImageTotals::of(&spp[0], w, h);
        let mut done = 0usize;
        for ((ow, oh), members) in groups {
            let chain = GpuChain::new(
                &self.ctx,
                ChainInput::Stats {
                    width: ow,
                    height: oh,
                    layers: self.layers.clone(),
                },
                self.config.clone(),
            )?;
            for i in members {
                let t = self.tiles[i];
                let sub = img.crop(t.outer.x0, t.outer.y0, ow, oh);
                chain.upload(&sub)?;
                drop(sub);
                let mut batch = crate::gpu::Batch::new(&self.ctx)?;
                batch.progress = batch_progress;
                chain.record_tile(&mut batch, t.placement(totals), budget.is_some())?;
                let tile_timings = batch.finish()?;
                let local = t.inner_local();
                let out = chain.download_in(Some(local))?;
                for (total, c) in report.counters.iter_mut().zip(chain.counters()?) {
                    *total += c;
                }
                if statistics {
                    let tile = chain.clean().download()?;
                    let all = clean.get_or_insert_with(|| {
                        let mut all = StatsImage::new(w, h);
                        for (layer, planes) in tile.layers() {
                            all.set(layer, vec![vec![0.0; n]; planes.len()]);
                        }
                        all
                    });
                    paste_stats(all, &tile, local, t.inner);
                }
                paste_rgb(&mut color, &out.color, t.inner);
                if want_error {
                    paste_rgb(&mut error, &out.error, t.inner);
                }
                if want_error {
                    paste(&mut dim, w, &out.dim, t.inner);
                }
                if let Some(p) = priority.as_mut() {
                    let plane = chain.download_priority_in(local)?;
                    paste(p, w, &plane, t.inner);
                }
                for (name, plane) in &out.debug {
                    let slot = match debug_planes.iter().position(|(n, _)| n == name) {
                        Some(k) => k,
                        None => {
                            debug_planes.push((name.clone(), vec![0.0; n]));
                            debug_planes.len() - 1
                        }
                    };
                    paste(&mut debug_planes[slot].1, w, plane, t.inner);
                }
                Tally::merge(&mut sums, out.stats);
                timings.extend(tile_timings);
                done += 1;
                if let Some(p) = progress {
                    p(done as f64 / self.tiles.len() as f64, "tile");
                }
            }
        }
        let samples = match (budget, priority) {
            (Some(t), Some(r)) => Some(self.allocate(img, &r, t, &mut timings)?),
            _ => None,
        };
        let stats = Tally::means(&sums);
        if self.config.method == Method::None {
            report.timings = timings.clone();
        }
        let out = DenoiseOutput {
            color,
            error: want_error.then_some(error),
            dim,
            samples,
            debug: debug_planes,
            report,
            timings,
            stats,
        };
        Ok((out, clean))
    }

    /// §9.2 on the whole image's priority map.
    fn allocate(
        &self,
        img: &StatsImage,
        priority: &[f32],
        budget: u32,
        timings: &mut Vec<KernelTiming>,
    ) -> Result<Vec<u32>> {
        let (w, h) = (self.width, self.height);
        let planes = SamplingPlanes::new(&self.ctx, w, h)?;
        let spp = PlaneSet::new(&self.ctx, "tiles.spp", w * h, 1)?;
        spp.upload_all(&[&img.get(Layer::Spp).expect("checked layers")[0]])?;
        planes.maps.upload_plane(0, priority)?;
        let mut batch = crate::gpu::Batch::new(&self.ctx)?;
        let floor = SamplingParams::with_options(self.config.method, &self.config.options)?.floor;
        sampling::record_allocation(
            &mut batch,
            planes.maps.plane(0),
            spp.plane(0),
            &planes,
            budget,
            floor,
        )?;
        timings.extend(batch.finish()?);
        sampling::download(&planes)
    }
}

/// Pastes the rectangle `from` of the tile's statistics `tile` into `all`
/// at `at` (same size), layer by layer.
fn paste_stats(all: &mut StatsImage, tile: &StatsImage, from: Rect, at: Rect) {
    let width = all.width;
    for (layer, planes) in tile.layers() {
        if let Some(dst) = all.get_mut(layer) {
            for (d, p) in dst.iter_mut().zip(planes) {
                paste(d, width, &crop(p, tile.width, from), at);
            }
        }
    }
}

fn paste(dst: &mut [f32], width: usize, src: &[f32], at: Rect) {
    let w = at.width();
    for (row, y) in (at.y0..at.y1).enumerate() {
        dst[y * width + at.x0..y * width + at.x1].copy_from_slice(&src[row * w..(row + 1) * w]);
    }
}

fn paste_rgb(dst: &mut RgbImage, src: &RgbImage, at: Rect) {
    let width = dst.width;
    for c in 0..3 {
        paste(&mut dst.planes[c], width, &src.planes[c], at);
    }
}

/// The crop of a `width`-wide plane to `r`.
pub fn crop(p: &[f32], width: usize, r: Rect) -> Vec<f32> {
    crop_plane(p, width, r.x0, r.y0, r.width(), r.height())
}
