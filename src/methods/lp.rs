//! LP: linear predictions with recursive least squares at sparse centres
//! (spec §3), as a sequence of kernels:
//!
//! ```text
//! gbf_pack      features and their variances → 4 vec4 planes (PACKED-LP)
//! fill          state ← 0 (no centres)
//! for g in 19, 9, 4, 2, 1 (pass t):
//!   lp_reach    reach ← per pixel, the largest r_opt of the centres of earlier
//!               passes in its row that reach it (PASS-SNAPSHOT)
//!   lp_centres  on the candidate grid of g: uncovered candidates → TSVD + RLS + r_opt
//! lp_gather     every pixel: mean of the covering centres' predictions (less
//!               those LP-PIXEL-TEST leaves out), error (LP-FEATNOISE),
//!               local dimension d, ΔMSE
//! ```
//!
//! [`record_lp`] records them on GPU-resident, sanitised statistics
//! ([`GpuStats`]) as a wavefront over the rows, with most of the state in a
//! ring of rows (LP-RING); [`run_cpu`] runs the scalar twins pass by pass.
//!
//! US patent 9,892,549 B2 (Disney) covers this method.

use std::sync::Arc;

use super::chain::ChainOutput;
use super::registry::{self, CpuResult, GpuStage, MethodInfo, StageRun, REGRESSION_LAYERS};
use super::sampling::{self, DimSource, SamplingParams};
use super::stats::GpuStats;
use super::tiles::Rect;
use super::{Method, Tally};
use crate::error::{Error, Result};
use crate::gpu::{plane_stride, Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
pub use crate::kernels::lp_centres::LpInputs;
use crate::kernels::{clipped_span, gbf_pack, lp_centres, lp_gather, lp_reach, lp_select};
use crate::options::Options;
use crate::reference;
use crate::reference::lp::{StateLayout, GRANULARITIES};
use crate::shared::{
    LpPush, LP_CENTRE_TEST, LP_OUTLIER_W, LP_PIXEL_TEST, LP_SKIP_COVERAGE, LP_SKIP_DMSE,
    LP_SKIP_ERROR, LP_VARSUB,
};

/// The parameters of one LP run.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct LpParams {
    /// [`LpPush::options`] bits.
    pub options: u32,
    /// Where the chain's pixel `(0, 0)` lies in the whole image: `(0, 0)`
    /// except for a tile ([`super::tiles`]), whose candidate grids keep the
    /// image's phase (§3.5 `px mod g = 0`, [`LpPush::phase_for`]).
    pub origin: (u32, u32),
}

impl LpParams {
    /// From the `lp.*` options of the registry. LP uses its one 19×19 window
    /// in every pass (§9.3 PASSES), so the pass does not change anything.
    pub fn new(opts: &Options) -> Result<LpParams> {
        let options = match opts.get("lp.error_mode") {
            "varsub" => LP_VARSUB,
            _ => 0,
        } | match opts.get("lp.centre_test") {
            "on" => LP_CENTRE_TEST,
            _ => 0,
        } | match opts.get("lp.pixel_test") {
            "on" => LP_PIXEL_TEST,
            _ => 0,
        } | match opts.get("lp.outlier_weight") {
            "clamped" => LP_OUTLIER_W,
            _ => 0,
        };
        Ok(LpParams {
            options,
            origin: (0, 0),
        })
    }

    fn push(&self, width: usize, height: usize, pass: usize) -> LpPush {
        LpPush {
            width: width as u32,
            height: height as u32,
            granularity: GRANULARITIES[pass],
            pass: pass as u32,
            options: self.options,
            out_stride: (plane_stride(width * height) / 4) as u32,
            phase: LpPush::phase_for(GRANULARITIES[pass], self.origin),
            row0: 0,
            ring_rows: 0,
        }
    }
}

/// Pixel rows per step of [`record_lp`]'s wavefront: each pass, and the
/// gather, advances by one band of this height per step.
pub const BAND_ROWS: u32 = 64;
/// Rows by which each pass (and the gather) trails the one before it: at
/// least LP's radius 9, so that a pass's candidates see every centre of the
/// earlier passes that can cover them (PASS-SNAPSHOT).
pub const LAG_ROWS: u32 = 16;
/// Rows of the ring of state planes 1..8 and of the reach planes
/// (LP-RING): a row's state is written at most `4·LAG_ROWS` rows behind the
/// front and read by the gather up to `5·LAG_ROWS + 9` rows behind it, so a
/// ring of more than `5·LAG_ROWS + BAND_ROWS + 9` rows never overwrites a
/// row that is still to be read.
pub const RING_ROWS: u32 = 160;
const _: () = assert!(RING_ROWS > 5 * LAG_ROWS + BAND_ROWS + 9 && LAG_ROWS >= 9);
const _: () = assert!(BAND_ROWS % 8 == 0 && LAG_ROWS % 8 == 0);

/// GPU scratch and output planes of one LP run.
#[derive(Debug)]
pub struct LpPlanes {
    /// State plane 0 of every pixel (the centre map: `pass + 1`, `r_opt`,
    /// `k`, `β0` R), vec4.
    pub state0: PlaneSet,
    /// State planes 1..8 ([`StateLayout`]), vec4, a ring of
    /// [`ring_rows`](Self::ring_rows) rows (LP-RING).
    pub ring: PlaneSet,
    /// The `lp_reach` planes of the centres before each pass (5), rings of
    /// [`ring_rows`](Self::ring_rows) rows.
    pub reach: PlaneSet,
    /// The queue of a band's centres (`lp_select` → `lp_centres`), u32.
    pub queue: PlaneSet,
    /// The features and their variances as 4 vec4 planes (PACKED-LP,
    /// [`gbf_pack`]'s layout), which `lp_centres` and `lp_gather` read: a
    /// vec4 load costs lavapipe about what one scalar load does.
    pub packed: PlaneSet,
    /// The outputs of [`lp_gather::OUTPUTS`] (bound as one buffer by the
    /// gather).
    pub out: PlaneSet,
    /// Rows of the rings: [`RING_ROWS`], or the height if it is smaller.
    pub ring_rows: u32,
}

impl LpPlanes {
    /// Allocates the planes for a `width × height` image. Fails with
    /// [`Error::Limit`] if the output planes, bound as one buffer, or a ring
    /// plane exceed `maxStorageBufferRange`.
    pub fn new(
        ctx: &Arc<GpuContext>,
        width: usize,
        height: usize,
        arena: Option<&Arc<GpuBuffer>>,
    ) -> Result<LpPlanes> {
        let n = width * height;
        let out_bytes = plane_stride(n) * lp_gather::OUTPUTS.len() as u64;
        let limit = ctx.info.max_storage_buffer_range as u64;
        if out_bytes > limit {
            return Err(Error::Limit(format!(
                "LP's {} output planes of {width}x{height} ({out_bytes} bytes, one binding) exceed maxStorageBufferRange ({limit} bytes)",
                lp_gather::OUTPUTS.len()
            )));
        }
        let ring_rows = Self::ring_rows(height);
        let ring_px = width * ring_rows as usize;
        if ring_px as u64 * 16 > limit {
            return Err(Error::Limit(format!(
                "LP's state ring of {ring_rows} rows of {width} pixels ({} bytes per plane) exceeds maxStorageBufferRange ({limit} bytes): use tiles (--tile)",
                ring_px * 16
            )));
        }
        let q = lp_select::queue_words(width, height);
        let (state0, queue, packed) = match arena {
            Some(a) => {
                let at = PlaneSet::bytes(4 * n, 1);
                let packed_at = at + PlaneSet::bytes(q, 1);
                (
                    PlaneSet::view(a, 0, 4 * n, 1)?,
                    PlaneSet::view(a, at, q, 1)?,
                    PlaneSet::view(a, packed_at, 4 * n, PACKED)?,
                )
            }
            None => (
                PlaneSet::new(ctx, "lp.state0", 4 * n, 1)?,
                PlaneSet::new(ctx, "lp.queue", q, 1)?,
                PlaneSet::new(ctx, "lp.packed", 4 * n, PACKED)?,
            ),
        };
        Ok(LpPlanes {
            state0,
            // A ring grows with the width, not the area: buffers of their
            // own, outside the arena (whose size the tiler's memory model
            // scales by area; it counts the rings by `ring_bytes`).
            ring: PlaneSet::new(ctx, "lp.ring", 4 * ring_px, StateLayout::PLANES - 1)?,
            reach: PlaneSet::new(ctx, "lp.reach", ring_px, GRANULARITIES.len())?,
            queue,
            packed,
            out: PlaneSet::new(ctx, "lp.out", n, lp_gather::OUTPUTS.len())?,
            ring_rows,
        })
    }

    /// Rows of the rings for an image `height` rows high.
    pub fn ring_rows(height: usize) -> u32 {
        RING_ROWS.min(height.max(1) as u32)
    }

    /// Bytes of the rings (state planes 1..8 and the reach planes) of a
    /// `width × height` image: they grow with the width, not the area.
    pub fn ring_bytes(width: usize, height: usize) -> u64 {
        let px = width * Self::ring_rows(height) as usize;
        PlaneSet::bytes(4 * px, StateLayout::PLANES - 1) + PlaneSet::bytes(px, GRANULARITIES.len())
    }

    /// Bytes of the scratch (state plane 0, the centre queue and the packed
    /// features) an arena must hold for `n` pixels: dead once `lp_gather`
    /// has written the outputs, except state plane 0
    /// ([`LpPlanes::kept_bytes`]), which [`download`] reads (centres,
    /// `r_opt`, ranks). With the prefilter (24 planes) or the outlier stage
    /// (23) in the same arena, its 21 planes add nothing to it.
    pub fn scratch_bytes(n: usize) -> u64 {
        PlaneSet::bytes(4 * n, 1)
            + PlaneSet::bytes(lp_select::queue_words(n, 1), 1)
            + PlaneSet::bytes(4 * n, PACKED)
    }

    /// Bytes at the start of the arena that must survive until [`download`]:
    /// state plane 0.
    pub fn kept_bytes(n: usize) -> u64 {
        PlaneSet::bytes(4 * n, 1)
    }

    /// The 9 state planes as the kernels bind them: plane 0 whole, 1..8 the
    /// ring.
    pub fn state(&self) -> [BufferSlice; 9] {
        std::array::from_fn(|k| {
            if k == 0 {
                self.state0.plane(0)
            } else {
                self.ring.plane(k - 1)
            }
        })
    }

    /// The output colour planes R, G, B.
    pub fn color(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(c))
    }

    /// The estimated MSE per channel (LP-FEATNOISE, see [`LpResult::error`]).
    pub fn error(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(3 + c))
    }

    /// ΔMSE per channel, `max(E, 0)·n^{-4/(d+4)}` (§3.5, §9.1), the input of
    /// the sampling step (§9).
    pub fn dmse(&self) -> [BufferSlice; 3] {
        std::array::from_fn(|c| self.out.plane(6 + c))
    }

    /// The local dimension `d_i` per pixel (§9.1): the mean TSVD rank `k_c`
    /// of the centres that predict it (0 at invalid pixels and where
    /// LP-PIXEL-TEST left every centre out).
    pub fn dim(&self) -> BufferSlice {
        self.out.plane(10)
    }
}

/// vec4 planes of [`LpPlanes::packed`].
const PACKED: usize = 4;

/// The bindings LP reads: `clean`'s colour, variances and counts, and the
/// features packed into `planes` by [`record_lp`] (valid from that packing
/// until the chain's arena is used by a later stage).
pub fn lp_inputs(s: &GpuStats, planes: &LpPlanes) -> LpInputs {
    LpInputs {
        packed: std::array::from_fn(|k| planes.packed.plane(k)),
        color: std::array::from_fn(|c| s.plane(Layer::Color, c)),
        cvar: std::array::from_fn(|c| s.plane(Layer::ColorVariance, c)),
        spp: s.plane(Layer::Spp, 0),
    }
}

/// Records LP on sanitised statistics `clean` (colour, albedo, normal, depth,
/// their variances and spp). Outputs stay on the GPU in `planes`.
///
/// LP-RING: the five passes and the gather run as a wavefront over the
/// rows. At each step every pass fits the candidates of one band of
/// [`BAND_ROWS`] rows, pass `t` [`LAG_ROWS`]`·t` rows behind the front and
/// the gather `5·LAG_ROWS` behind it. Before its band, a pass computes the
/// reach of the centres of the earlier passes on the rows its candidates'
/// coverage test newly reads (up to 9 rows below the band), where the
/// earlier passes are complete. Pass `t`'s centres are therefore those of
/// the spec's pass-by-pass order (PASS-SNAPSHOT), but a row's state is dead
/// once the gather has passed it, so state planes 1..8 (128 of the state's
/// 144 bytes per pixel) are a ring of [`RING_ROWS`] rows.
pub fn record_lp(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &LpPlanes,
    params: LpParams,
) -> Result<()> {
    let (w, h) = (clean.width, clean.height);
    let height = h as u32;
    let inp = lp_inputs(clean, planes);
    // PACKED-LP: the features and their variances as 4 vec4 planes.
    let (feat, var) = super::wlr::features(clean);
    gbf_pack::record(
        batch,
        precision,
        w as u32,
        height,
        (0, height),
        feat,
        var,
        clean.plane_quads(Layer::Spp, 0),
        inp.packed,
    )?;
    let state = planes.state();
    let passes = GRANULARITIES.len();
    batch.fill(planes.state0.all(), 0);
    // Per pass: the rows whose reach is computed (the gather needs none:
    // LP-GATHER-UNION).
    let mut reach_done = [0u32; GRANULARITIES.len()];
    let mut front = 0u32;
    while front < height + passes as u32 * LAG_ROWS {
        for t in 0..=passes {
            // This pass's band: the front's band moved up by the lag (the
            // first one clipped at row 0).
            let (lag, end) = (t as u32 * LAG_ROWS, front + BAND_ROWS);
            if end <= lag || front.saturating_sub(lag) >= height {
                continue;
            }
            let (a, b) = (front.saturating_sub(lag), (end - lag).min(height));
            let push = LpPush {
                pass: t as u32,
                ring_rows: planes.ring_rows,
                ..params.push(w, h, t.min(passes - 1))
            };
            if t < passes {
                let done = &mut reach_done[t];
                let reach_end = (b + reference::lp::RADIUS as u32).min(height);
                if *done < reach_end {
                    lp_reach::record(
                        batch,
                        precision,
                        &push,
                        state[0],
                        planes.reach.plane(t),
                        (*done, reach_end),
                    )?;
                    *done = reach_end;
                }
                // The grid rows whose candidates lie in rows [a, b).
                let g = GRANULARITIES[t];
                let fy = push.phase_xy().1;
                let grid = |y: u32| y.saturating_sub(fy).div_ceil(g);
                lp_centres::record(
                    batch,
                    precision,
                    &push,
                    &inp,
                    planes.reach.plane(t),
                    planes.queue.plane(0),
                    state,
                    Some((grid(a), grid(b))),
                )?;
            } else {
                lp_gather::record(
                    batch,
                    precision,
                    &push,
                    &inp,
                    state,
                    planes.out.all(),
                    (a, b),
                )?;
            }
        }
        front += BAND_ROWS;
    }
    Ok(())
}

/// Fraction of the pixels of a [`LpResult::centre_pass`] plane (or a crop of
/// it) that became centres.
pub fn centre_fraction(centre_pass: &[f32]) -> f64 {
    let n = centre_pass.len().max(1);
    centre_pass.iter().filter(|&&p| is_centre(p)).count() as f64 / n as f64
}

/// Whether a centre-pass value marks a centre (pass + 1 > 0).
fn is_centre(centre_pass: f32) -> bool {
    centre_pass > 0.0
}

/// What a run's centre map says about its work, for the statistics of a
/// run ([`Census::stats`]) and `bench`'s flop counts: the centres of a
/// rectangle of the image, the work of their fits
/// ([`lp_centres::flops_of_centre`] of each one's rank) and the pixels they
/// cover (each one's `(2 r_opt + 1)²` square, clipped to the image), which
/// the gather predicts one by one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Census {
    /// The map's width and height, and the rectangle counted.
    size: (usize, usize),
    rect: Rect,
    /// Centres in it.
    pub centres: usize,
    /// Σ over those centres of [`lp_centres::flops_of_centre`].
    pub centre_flops: f64,
    /// Σ over those centres of the pixels their square covers.
    pub covered: f64,
}

impl Census {
    /// An empty census of the `rect` (the whole image when `None`) of a
    /// `width × height` centre map.
    fn new(width: usize, height: usize, rect: Option<Rect>) -> Census {
        let rect = rect.unwrap_or(Rect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        });
        Census {
            size: (width, height),
            rect,
            centres: 0,
            centre_flops: 0.0,
            covered: 0.0,
        }
    }

    /// Counts pixel `q` (raster order) of the map, whose state is
    /// (pass + 1, `r_opt`, `k`).
    fn add(&mut self, q: usize, [pass, r_opt, k]: [f32; 3]) {
        let ((w, h), r) = (self.size, self.rect);
        let (x, y) = (q % w.max(1), q / w.max(1));
        if !is_centre(pass) || x < r.x0 || x >= r.x1 || y < r.y0 || y >= r.y1 {
            return;
        }
        let ro = r_opt.max(0.0) as usize;
        self.centres += 1;
        self.centre_flops += lp_centres::flops_of_centre(k.max(0.0) as u32);
        self.covered += (clipped_span(x, ro, w) * clipped_span(y, ro, h)) as f64;
    }

    /// Over the rectangle's pixels: `centre_fraction` (centres),
    /// `centre_flops` (their fits' work) and `covering` (the pixels their
    /// squares cover; per pixel, the centres covering it on average). Each
    /// sum is a whole number, so a tiled run's equals the whole run's.
    pub fn stats(&self) -> Vec<Tally> {
        let pixels = self.rect.width() * self.rect.height();
        [
            ("centre_fraction", self.centres as f64),
            ("centre_flops", self.centre_flops),
            ("covering", self.covered),
        ]
        .into_iter()
        .map(|(name, sum)| Tally {
            name: name.into(),
            sum,
            pixels,
        })
        .collect()
    }
}

/// What an LP run gives back on the host.
#[derive(Clone, Debug)]
pub struct LpResult {
    /// The reconstruction (§3.5: mean of the covering centres' predictions,
    /// less those LP-PIXEL-TEST leaves out; the input where it leaves out
    /// all), clamped to ≥ 0.
    pub color: RgbImage,
    /// Estimated MSE per pixel and channel (LP-FEATNOISE):
    /// `E_i[ch] = mean_c max(ξ̂_c,ch, 0) + (Σ_j |ū[ch][j]| σ_ij)²` over the
    /// centres c predicting i, `ū = mean_c u_c`, `σ_ij² = var(x_ij)` (≥ 0; 0
    /// at invalid pixels, `v_i` where no centre predicts i; see
    /// `reference::lp_gather::OUTPUTS`).
    pub error: RgbImage,
    /// ΔMSE per pixel and channel, `E_i·n_i^{-4/(d_i+4)}` (§3.5, §9.1), for
    /// sampling.
    pub dmse: RgbImage,
    /// Centres per pixel that cover it and predict it (LP-PIXEL-TEST).
    pub coverage: Vec<f32>,
    /// Local dimension `d_i` per pixel (§9.1): mean `k_c` of the centres
    /// that predict it (0 at invalid pixels and where none does).
    pub dim: Vec<f32>,
    /// Per pixel: pass + 1 of the pass that made it a centre (1..=5), 0
    /// elsewhere.
    pub centre_pass: Vec<f32>,
    /// Per pixel: the chosen prediction radius `r_opt` (0..=9, §3.4) at
    /// centres, -1 elsewhere.
    pub r_opt: Vec<f32>,
    /// Per pixel: the TSVD rank `k_c` (§0.6) at centres, -1 elsewhere.
    pub rank: Vec<f32>,
}

impl LpResult {
    fn new(width: usize, height: usize, out: Vec<Vec<f32>>, state0: &[f32]) -> LpResult {
        let n = width * height;
        let rgb = |k: usize| {
            RgbImage::from_planes(width, height, std::array::from_fn(|c| out[k + c].clone()))
        };
        let is_centre = |q: usize| state0[4 * q] > 0.0;
        let at = |s: usize| -> Vec<f32> {
            (0..n)
                .map(|q| {
                    if is_centre(q) {
                        state0[4 * q + s]
                    } else {
                        -1.0
                    }
                })
                .collect()
        };
        LpResult {
            color: rgb(0),
            error: rgb(3),
            dmse: rgb(6),
            coverage: out[9].clone(),
            dim: out[10].clone(),
            centre_pass: (0..n).map(|q| state0[4 * q]).collect(),
            r_opt: at(StateLayout::R_OPT),
            rank: at(StateLayout::K),
        }
    }

    /// Fraction of the pixels that became centres.
    pub fn centre_fraction(&self) -> f64 {
        centre_fraction(&self.centre_pass)
    }

    /// The [`Census`] of the `rect` (the whole image when `None`) of this
    /// `width`-wide result.
    pub fn census(&self, width: usize, rect: Option<Rect>) -> Census {
        let height = self.centre_pass.len() / width.max(1);
        let mut c = Census::new(width, height, rect);
        for q in 0..self.centre_pass.len() {
            c.add(q, [self.centre_pass[q], self.r_opt[q], self.rank[q]]);
        }
        c
    }

    /// The debug layers of issue #4: centre mask (pass + 1), r_opt, rank,
    /// coverage count, local dimension, ΔMSE.
    pub fn debug_layers(&self) -> Vec<(String, Vec<f32>)> {
        let mut v = vec![
            ("centre_pass".into(), self.centre_pass.clone()),
            ("r_opt".into(), self.r_opt.clone()),
            ("rank".into(), self.rank.clone()),
            ("coverage".into(), self.coverage.clone()),
            ("dim".into(), self.dim.clone()),
        ];
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            v.push((format!("dmse.{name}"), self.dmse.planes[c].clone()));
        }
        v
    }
}

/// Downloads the planes of a finished [`record_lp`].
pub fn download(planes: &LpPlanes, width: usize, height: usize) -> Result<LpResult> {
    let out = planes.out.download_all()?;
    let state0 = planes.state0.download_plane::<f32>(0)?;
    Ok(LpResult::new(width, height, out, &state0))
}

/// The [`Census`] of the `rect` (the whole image when `None`) of a finished
/// [`record_lp`] on a `width × height` image, counted on the host in chunks
/// of the device's centre map (no copy of it).
pub fn census(
    planes: &LpPlanes,
    width: usize,
    height: usize,
    rect: Option<Rect>,
) -> Result<Census> {
    let mut c = Census::new(width, height, rect);
    let mut q = 0;
    planes.state0.for_each_group(0, 4, |t| {
        c.add(q, [t[0], t[StateLayout::R_OPT], t[StateLayout::K]]);
        q += 1;
    })?;
    Ok(c)
}

/// The CPU path: the scalar twins in the order of [`record_lp`], on
/// sanitised statistics. `progress` prints each pass on stderr once the
/// run has taken more than a second.
pub fn run_cpu(clean: &StatsImage, params: LpParams, progress: bool) -> Result<LpResult> {
    let started = std::time::Instant::now();
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let need = |l: Layer| {
        clean
            .get(l)
            .ok_or_else(|| Error::BadData(format!("LP needs the {} layer", l.name())))
    };
    let (col, cvar) = (need(Layer::Color)?, need(Layer::ColorVariance)?);
    let (nrm, nvar) = (need(Layer::Normal)?, need(Layer::NormalVariance)?);
    let (dep, dvar) = (need(Layer::Depth)?, need(Layer::DepthVariance)?);
    let (alb, avar) = (need(Layer::Albedo)?, need(Layer::AlbedoVariance)?);
    let spp = &need(Layer::Spp)?[0];
    let p = reference::lp::Planes {
        width: w,
        height: h,
        feat: [
            &nrm[0], &nrm[1], &nrm[2], &dep[0], &alb[0], &alb[1], &alb[2],
        ],
        var: [
            &nvar[0], &nvar[1], &nvar[2], &dvar[0], &avar[0], &avar[1], &avar[2],
        ],
        color: [&col[0], &col[1], &col[2]],
        cvar: [&cvar[0], &cvar[1], &cvar[2]],
        spp,
    };
    let mut state = vec![vec![0.0f32; 4 * n]; StateLayout::PLANES];
    let mut reach = vec![-1.0f32; n];
    for pass in 0..GRANULARITIES.len() {
        let push = params.push(w, h, pass);
        reference::lp_reach::lp_reach(&push, &state[0], &mut reach);
        let made = reference::lp_centres::lp_centres(&push, &p, &reach, &mut state);
        let t = started.elapsed().as_secs_f64();
        if progress && t > 1.0 {
            log::info!(
                "lp pass g={} (cpu): {made} centres ({t:.1} s)",
                GRANULARITIES[pass]
            );
        }
    }
    let mut out = vec![vec![0.0f32; n]; lp_gather::OUTPUTS.len()];
    // The reach of every pass's centres.
    let push = LpPush {
        pass: GRANULARITIES.len() as u32,
        ..params.push(w, h, 0)
    };
    reference::lp_reach::lp_reach(&push, &state[0], &mut reach);
    reference::lp_gather::lp_gather(&push, &p, &reach, &state, &mut out);
    Ok(LpResult::new(w, h, out, &state[0]))
}

/// LP's entry in the method registry.
pub static INFO: MethodInfo = MethodInfo {
    method: Method::Lp,
    name: "lp",
    about: "linear predictions at sparse centres (spec §3; US patent 9,892,549 B2)",
    needs: &REGRESSION_LAYERS,
    prefilter_auto: true,
    outliers_auto: true,
    pyramid_auto: false,
    blend: super::blend::BlendDefaults {
        auto: true,
        k: 0.125,
        ..super::blend::BlendDefaults::BASE
    },
    // MAP-WLR: WLR's estimate places the adaptive passes' samples.
    map_method: Method::Wlr,
    passes: 5,
    // LP-CAP: LP's map concentrates samples at emitter edges.
    pass_cap: Some(4.0),
    map_check: true,
    sampling: SamplingParams {
        eps: sampling::EPS_DEFAULT,
        sigma_s: sampling::SIGMA_LP,
        e_is_dmse: true,
        dim: DimSource::Plain,
        floor: 0.6,
    },
    error_scale: 0.8,
    // PYRAMID-ERROR-SCALE: error_scale × 2.17.
    pyramid_error_scale: 1.7,
    // TEMPORAL-TEST-SCALE: its output's noise over its estimate, over WLR's
    // (0.17 and 0.20 on two sets of scenes).
    inflate_scale: 0.17,
    align: 1,
    halo: |_| Ok(reference::lp::RADIUS * (GRANULARITIES.len() + 1)),
    arena_bytes: |_, (w, h)| LpPlanes::scratch_bytes(w * h),
    arena_kept: LpPlanes::kept_bytes,
    options_for: registry::same_options,
    ring_bytes: |_, (w, h)| LpPlanes::ring_bytes(w, h),
    gpu: |a| {
        Ok(Box::new(LpStage {
            planes: LpPlanes::new(a.ctx, a.size.0, a.size.1, a.arena)?,
            params: LpParams::new(&a.config.options)?,
        }))
    },
    cpu: |clean, a| {
        let params = LpParams::new(&a.options)?;
        let r = run_cpu(clean, params, a.progress)?;
        Ok(CpuResult {
            debug: if a.debug {
                r.debug_layers()
            } else {
                Vec::new()
            },
            stats: r.census(clean.width, None).stats(),
            map_error: Some(r.dmse.clone()),
            color: r.color,
            error: r.error,
            dim: r.dim,
        })
    },
};

/// LP's GPU stage.
struct LpStage {
    planes: LpPlanes,
    params: LpParams,
}

impl GpuStage for LpStage {
    fn record(&self, batch: &mut Batch, run: &StageRun) -> Result<()> {
        let c = run.config;
        let skip = [
            (c.error || c.debug, LP_SKIP_ERROR),
            (run.maps || c.debug, LP_SKIP_DMSE),
            (c.debug, LP_SKIP_COVERAGE),
        ];
        let params = LpParams {
            origin: run.origin,
            options: super::chain::skip_bits(self.params.options, &skip),
        };
        record_lp(batch, run.precision, run.stats, &self.planes, params)
    }

    fn color(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.color()
    }

    fn error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.error()
    }

    /// ΔMSE (§3.5 already folds in the rate).
    fn sampling_error(&self, _: &GpuStats) -> [BufferSlice; 3] {
        self.planes.dmse()
    }

    fn dim(&self) -> (BufferSlice, bool) {
        (self.planes.dim(), false)
    }

    fn download(
        &self,
        _: &GpuStats,
        (w, h): (usize, usize),
        rect: Option<Rect>,
        debug: bool,
        out: &mut ChainOutput,
    ) -> Result<()> {
        // All of LP's planes only for the debug layers; the census without
        // a host copy of the centre map.
        let census = if debug {
            let r = download(&self.planes, w, h)?;
            out.debug = r.debug_layers();
            r.census(w, rect)
        } else {
            census(&self.planes, w, h, rect)?
        };
        out.stats.extend(census.stats());
        Ok(())
    }
}
