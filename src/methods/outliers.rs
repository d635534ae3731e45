//! The energy-preserving outlier stage (spec §4.4), for every method, placed
//! in the chain as spec §1 draws it:
//!
//! ```text
//! sanitize → remove (steps 1–3) → G-buffer prefilter → method → restore (step 4) → sample map
//!
//! remove:   outlier_grey      order-preserving key of grey (0: invalid)
//!           (per OUTLIER-CLIP round, on a copy of the keys:
//!            outlier_rows, outlier_clip   key ← 0 for a light or a far spike)
//!           outlier_rows      row (count, mean, M2) of grey with and without x, R = 14
//!           outlier_detect    merge → m, sd without o; queue the spikes; e ← 0
//!           outlier_median    (indirect, per queued spike) the median pixel; e = y − y_q*
//!           outlier_median    (OUTLIER_APPLY) its colour and variance → the sanitised statistics
//! restore:  box_rows          row sums of ŷ (3) and of the valid count, R = 43
//!           outlier_weights   ρ = e / Σ_{87×87} ŷ (or e/|Ω| in a dark window),
//!                             (indirect, per queued pixel; 0 elsewhere)
//!           box_rows ×2       row sums of ρ and of the dark shares (4 + 2 planes)
//!           outlier_spread    ŷ ← max(0, ŷ(1 + Σρ) + Σ add), in place
//!           (OUTLIER-WIDE, when on: the weights skip and mark the outliers
//!            whose excess is above `outliers.wide` of their window's grey
//!            sum; then the four passes again, R = 215, for those)
//! ```
//!
//! Every pass is a gather over fixed windows (box sums split into a row and a
//! column pass), so the stage is deterministic and costs O(R) per pixel.
//! The CPU path runs [`crate::reference::outliers`] from the definitions.

use std::sync::Arc;

use super::stats::GpuStats;
use super::Method;
use crate::error::Result;
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, StatsImage};
use crate::kernels::box_rows::BoxPlanes;
use crate::kernels::{
    box_rows, outlier_clip, outlier_detect, outlier_grey, outlier_median, outlier_rows,
    outlier_spread, outlier_weights,
};
use crate::options::Options;
use crate::reference::outliers::{self as reference, DETECT_RADIUS, SPREAD_RADIUS, WIDE_RADIUS};
use crate::shared::{OutlierPush, DETECT_RIM, WEIGHTS_NARROW, WEIGHTS_WIDE};

/// Rounds of OUTLIER-CLIP before detection: `outliers.clip`, else the
/// registry's default (`reference::outliers` documents the decision).
pub fn clip_rounds(options: &Options) -> Result<u32> {
    options.value("outliers.clip")
}

/// How steps 1–3 detect the spikes ([`Detection::of`] gives the
/// registry's defaults).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Detection {
    /// OUTLIER-CLIP's rounds (`outliers.clip`).
    pub clip: u32,
    /// OUTLIER-RIM (`outliers.rim`, on by default).
    pub rim: bool,
}

impl Detection {
    /// `outliers.clip` and `outliers.rim`, else the registry's defaults.
    pub fn of(options: &Options) -> Result<Detection> {
        Ok(Detection {
            clip: clip_rounds(options)?,
            rim: options.get("outliers.rim") == "on",
        })
    }

    /// [`OutlierPush::mode`] of `outlier_detect`.
    fn mode(self) -> u32 {
        if self.rim {
            DETECT_RIM
        } else {
            0
        }
    }
}

/// OUTLIER-WIDE's fraction: `outliers.wide`, else the registry's default
/// ([`reference::WIDE_FRACTION`]); 0 is the spec's single window.
pub fn wide_fraction(options: &Options) -> Result<f64> {
    options.value("outliers.wide")
}

/// `options` with OUTLIER-WIDE off (`outliers.wide=0`): what a tiled run
/// spreads with, since the wide window would add 430 px to every tile's
/// halo ([`crate::methods::tiles`]).
pub fn one_window(options: &Options) -> Result<Options> {
    let mut pairs: Vec<String> = options
        .keys()
        .filter(|&k| k != "outliers.wide")
        .map(|k| format!("{k}={}", options.get(k)))
        .collect();
    pairs.push("outliers.wide=0".into());
    Options::parse(&pairs)
}

/// Whether the outlier stage runs (`--outliers`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Outliers {
    /// The method's default ([`Outliers::default_for`]).
    #[default]
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

impl Outliers {
    /// Parses `auto`, `on` or `off`.
    pub fn parse(s: &str) -> Option<Outliers> {
        match s {
            "auto" => Some(Outliers::Auto),
            "on" => Some(Outliers::On),
            "off" => Some(Outliers::Off),
            _ => None,
        }
    }

    /// The method's default ([`super::MethodInfo::outliers_auto`]): on for
    /// every reconstruction, off for `none` (whose output is the plain Monte
    /// Carlo mean by definition).
    pub fn default_for(method: Method) -> bool {
        method.info().outliers_auto
    }

    /// Whether the stage runs for `method`.
    pub fn resolve(self, method: Method) -> bool {
        match self {
            Outliers::Auto => Outliers::default_for(method),
            Outliers::On => true,
            Outliers::Off => false,
        }
    }
}

/// The push constants of the stage's kernels for a `w × h` image: the spec's
/// constants (§4.4), window radius `radius`, `box_rows` mode `mode`.
pub fn push(w: usize, h: usize, radius: usize, mode: u32) -> OutlierPush {
    OutlierPush {
        width: w as u32,
        height: h as u32,
        radius: radius as u32,
        mode,
        min_n: reference::MIN_NEIGHBOURS,
        k_sigma: reference::K_SIGMA as f32,
        dark: reference::DARK as f32,
        ..Default::default()
    }
}

/// The stage's planes: two six-plane scratch sets, the excess `e` (3), the
/// weights (6), the grey keys (1) and OUTLIER-CLIP's kept keys (1, in the
/// scratch of the restoration's weights); and the queue of detected pixels.
#[derive(Debug)]
pub struct OutlierPlanes {
    /// Scratch of each step ([`SCRATCH`] planes): dead between
    /// [`record_remove`] and [`record_restore`], so it may live in the
    /// chain's arena.
    planes: PlaneSet,
    /// The removed excess `e_o` (3 planes), alive from the removal to the
    /// restoration.
    excess: PlaneSet,
    queue: GpuBuffer,
    width: usize,
    height: usize,
    /// OUTLIER-CLIP's rounds and OUTLIER-RIM.
    detection: Detection,
    /// OUTLIER-WIDE's fraction (0: off).
    wide: f32,
}

/// Scratch planes of the stage: row summaries (6), replacements (6) and the
/// kept keys of OUTLIER-CLIP (1) of the detection, or the box sums (12) and
/// weights (6) of the restoration; the keys of grey (1).
pub const SCRATCH: usize = 19;

impl OutlierPlanes {
    /// Allocates the planes for a `w × h` image, whose detection runs as
    /// `detection` says and whose restoration sends excesses
    /// above `wide` of their window to OUTLIER-WIDE's (0: never); the
    /// scratch in an arena from a byte offset ([`PlaneSet::view`]) when
    /// given.
    pub fn new(
        ctx: &Arc<GpuContext>,
        w: usize,
        h: usize,
        detection: Detection,
        wide: f64,
        arena: Option<(&Arc<GpuBuffer>, u64)>,
    ) -> Result<OutlierPlanes> {
        let planes = match arena {
            Some((a, offset)) => PlaneSet::view(a, offset, w * h, SCRATCH)?,
            None => PlaneSet::new(ctx, "outliers", w * h, SCRATCH)?,
        };
        Ok(OutlierPlanes {
            planes,
            excess: PlaneSet::new(ctx, "outliers.excess", w * h, 3)?,
            queue: GpuBuffer::new(
                ctx,
                "outliers.queue",
                4 * outlier_detect::queue_words(w, h) as u64,
            )?,
            width: w,
            height: h,
            detection,
            wide: wide as f32,
        })
    }

    fn set<const N: usize>(&self, first: usize) -> [BufferSlice; N] {
        std::array::from_fn(|i| self.planes.plane(first + i))
    }

    /// The removed excess `e_o` per channel (0 where nothing was detected).
    pub fn excess(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.excess.plane(c))
    }
}

/// Records steps 1–3 on the sanitised statistics `clean`, in place.
pub fn record_remove(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    p: &OutlierPlanes,
) -> Result<()> {
    let (w, h) = (p.width, p.height);
    let color: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::Color, c));
    let var: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(Layer::ColorVariance, c));
    let spp = clean.plane(Layer::Spp, 0);
    let pu = push(w, h, DETECT_RADIUS, 0);
    let rows = p.set::<6>(0);
    let rep = p.set::<6>(6);
    let keys = p.planes.plane(18);
    outlier_grey::record(batch, precision, &pu, color, spp, keys)?;
    // OUTLIER-CLIP: the detection's statistics come from the kept keys; the
    // isolation test and the median read every valid pixel's.
    let stats_keys = if p.detection.clip > 0 {
        let kept = p.planes.plane(12);
        batch.copy(keys, kept);
        for _ in 0..p.detection.clip {
            outlier_rows::record(batch, precision, &pu, kept, rows)?;
            outlier_clip::record(batch, precision, &pu, kept, rows, var)?;
        }
        kept
    } else {
        keys
    };
    outlier_rows::record(batch, precision, &pu, stats_keys, rows)?;
    let queue = p.queue.slice();
    let detect = OutlierPush {
        mode: p.detection.mode(),
        ..pu
    };
    outlier_detect::record(
        batch,
        precision,
        &detect,
        color,
        var,
        spp,
        keys,
        rows,
        p.excess(),
        queue,
    )?;
    for step in [outlier_median::Step::Find, outlier_median::Step::Apply] {
        outlier_median::record(
            batch,
            precision,
            &pu,
            step,
            color,
            var,
            keys,
            queue,
            rep,
            p.excess(),
        )?;
    }
    Ok(())
}

/// Records step 4 on the method's colour planes `color`, in place; `spp` gives
/// the valid pixels. With OUTLIER-WIDE on, two spreads: the 87×87 window's
/// outliers, then, over the wide window, the ones its weights marked.
pub fn record_restore(
    batch: &mut Batch,
    precision: Precision,
    spp: BufferSlice,
    color: [BufferSlice; 3],
    p: &OutlierPlanes,
) -> Result<()> {
    if p.wide > 0.0 {
        record_spread(
            batch,
            precision,
            spp,
            color,
            p,
            SPREAD_RADIUS,
            WEIGHTS_NARROW,
        )?;
        record_spread(batch, precision, spp, color, p, WIDE_RADIUS, WEIGHTS_WIDE)
    } else {
        record_spread(batch, precision, spp, color, p, SPREAD_RADIUS, 0)
    }
}

/// One spread of the outliers `mode` selects over windows of radius `r`.
fn record_spread(
    batch: &mut Batch,
    precision: Precision,
    spp: BufferSlice,
    color: [BufferSlice; 3],
    p: &OutlierPlanes,
    r: usize,
    mode: u32,
) -> Result<()> {
    let (w, h) = (p.width, p.height);
    let sum = push(w, h, r, 0);
    let a = p.set::<6>(0);
    let b = p.set::<6>(6);
    let weights = p.set::<6>(12);
    // The colour's row sums and the valid count in one dispatch.
    box_rows::record(
        batch,
        precision,
        &sum,
        BoxPlanes::SumsAndCount(&color),
        spp,
        &a[..4],
    )?;
    outlier_weights::record(
        batch,
        precision,
        &OutlierPush {
            mode,
            wide: p.wide,
            ..sum
        },
        p.excess(),
        [a[0], a[1], a[2]],
        a[3],
        p.queue.slice(),
        weights,
    )?;
    box_rows::record(
        batch,
        precision,
        &sum,
        BoxPlanes::Sums(&weights[..4]),
        spp,
        &b[..4],
    )?;
    box_rows::record(
        batch,
        precision,
        &sum,
        BoxPlanes::Sums(&weights[4..]),
        spp,
        &b[4..],
    )?;
    outlier_spread::record(batch, precision, &sum, b, spp, color)?;
    Ok(())
}

/// The debug layers of the stage: `outlier_mask` (1 where some channel's
/// excess is non-zero) and `outlier_energy.R/G/B` (the excess `e_o`).
pub fn debug_layers(excess: &[Vec<f32>; 3]) -> Vec<(String, Vec<f32>)> {
    let n = excess[0].len();
    let mask = (0..n)
        .map(|i| {
            if (0..3).any(|c| excess[c][i] != 0.0) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    let mut v = vec![("outlier_mask".to_string(), mask)];
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        v.push((format!("outlier_energy.{name}"), excess[c].clone()));
    }
    v
}

/// Downloads the excess planes of the last run.
pub fn download_excess(p: &OutlierPlanes) -> Result<[Vec<f32>; 3]> {
    Ok([
        p.excess.download_plane(0)?,
        p.excess.download_plane(1)?,
        p.excess.download_plane(2)?,
    ])
}

/// What [`remove_cpu`] removed, for [`restore_cpu`].
#[derive(Clone, Debug)]
pub struct Removed {
    /// Detected pixels.
    pub mask: Vec<bool>,
    /// The excess per channel, f64.
    pub excess: [Vec<f64>; 3],
}

impl Removed {
    /// The excess as f32 planes (for [`debug_layers`]).
    pub fn excess_f32(&self) -> [Vec<f32>; 3] {
        std::array::from_fn(|c| self.excess[c].iter().map(|&v| v as f32).collect())
    }
}

/// Steps 1–3 as `detection` says on sanitised statistics, in place (CPU
/// path).
pub fn remove_cpu(clean: &mut StatsImage, detection: Detection) -> Removed {
    let (w, h) = (clean.width, clean.height);
    let spp = clean.get(Layer::Spp).unwrap()[0].clone();
    let mut color: [Vec<f32>; 3] = clean
        .get(Layer::Color)
        .unwrap()
        .to_vec()
        .try_into()
        .unwrap();
    let mut var: [Vec<f32>; 3] = clean
        .get(Layer::ColorVariance)
        .unwrap()
        .to_vec()
        .try_into()
        .unwrap();
    let (mask, excess) = reference::remove(
        w,
        h,
        &mut color,
        &mut var,
        &spp,
        detection.clip,
        detection.rim,
    );
    clean.set(Layer::Color, color.to_vec());
    clean.set(Layer::ColorVariance, var.to_vec());
    Removed { mask, excess }
}

/// Step 4 on a reconstruction (CPU path), in place, with OUTLIER-WIDE's
/// fraction `wide`.
pub fn restore_cpu(
    w: usize,
    h: usize,
    spp: &[f32],
    removed: &Removed,
    wide: f64,
    color: &mut [Vec<f32>; 3],
) {
    reference::restore(w, h, spp, &removed.mask, &removed.excess, wide, color);
}
