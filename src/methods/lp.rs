//! LP: linear predictions with recursive least squares at sparse centres
//! (spec §3), as a sequence of kernels:
//!
//! ```text
//! fill          state ← 0 (no centres)
//! for g in 19, 9, 4, 2, 1 (pass t):
//!   lp_reach    reach ← per pixel, the largest r_opt of the centres of its row
//!               that reach it (PASS-SNAPSHOT: coverage from earlier passes only)
//!   lp_centres  on the candidate grid of g: uncovered candidates → TSVD + RLS + r_opt
//! lp_reach      once more, for the gather
//! lp_gather     every pixel: mean of the covering centres' predictions, error
//!               (LP-FEATNOISE), local dimension d, ΔMSE
//! ```
//!
//! [`record_lp`] records them on GPU-resident, sanitised statistics
//! ([`GpuStats`]); [`run_cpu`] runs the scalar twins in the same order.
//!
//! US patent 9,892,549 B2 (Disney) covers this method.

use std::sync::Arc;

use super::stats::GpuStats;
use crate::error::{Error, Result};
use crate::gpu::{plane_stride, Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, RgbImage, StatsImage};
pub use crate::kernels::lp_centres::LpInputs;
use crate::kernels::{lp_centres, lp_gather, lp_reach, lp_select};
use crate::options::Options;
use crate::reference;
use crate::reference::lp::{StateLayout, GRANULARITIES};
use crate::shared::{LpPush, LP_VARSUB};

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
        }
    }
}

/// GPU scratch and output planes of one LP run.
#[derive(Debug)]
pub struct LpPlanes {
    /// The per-centre state: [`StateLayout::PLANES`] vec4 planes.
    pub state: PlaneSet,
    /// The `lp_reach` plane of the current state.
    pub reach: PlaneSet,
    /// The queue of a band's centres (`lp_select` → `lp_centres`), u32.
    pub queue: PlaneSet,
    /// The outputs of [`lp_gather::OUTPUTS`] (bound as one buffer by the
    /// gather).
    pub out: PlaneSet,
}

impl LpPlanes {
    /// Allocates the planes for a `width × height` image. Fails with
    /// [`Error::Limit`] if the output planes, bound as one buffer, exceed
    /// `maxStorageBufferRange`.
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
        let q = lp_select::queue_words(width, height);
        let (state, reach, queue) = match arena {
            Some(a) => (
                PlaneSet::view(a, 0, 4 * n, StateLayout::PLANES)?,
                PlaneSet::view(a, Self::state_bytes(n), n, 1)?,
                PlaneSet::view(a, Self::state_bytes(n) + PlaneSet::bytes(n, 1), q, 1)?,
            ),
            None => (
                PlaneSet::new(ctx, "lp.state", 4 * n, StateLayout::PLANES)?,
                PlaneSet::new(ctx, "lp.reach", n, 1)?,
                PlaneSet::new(ctx, "lp.queue", q, 1)?,
            ),
        };
        Ok(LpPlanes {
            state,
            reach,
            queue,
            out: PlaneSet::new(ctx, "lp.out", n, lp_gather::OUTPUTS.len())?,
        })
    }

    fn state_bytes(n: usize) -> u64 {
        PlaneSet::bytes(4 * n, StateLayout::PLANES)
    }

    /// Bytes of the scratch (state, reach and the centre queue) an arena
    /// must hold for `n` pixels: dead once `lp_gather` has written the
    /// outputs, except the first state plane ([`LpPlanes::kept_bytes`]),
    /// which [`download`] reads (centres, `r_opt`, ranks).
    pub fn scratch_bytes(n: usize) -> u64 {
        Self::state_bytes(n)
            + PlaneSet::bytes(n, 1)
            + PlaneSet::bytes(n + lp_select::HEADER_WORDS, 1)
    }

    /// Bytes at the start of the arena that must survive until [`download`]:
    /// the first state plane.
    pub fn kept_bytes(n: usize) -> u64 {
        PlaneSet::bytes(4 * n, 1)
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
    /// of the centres that cover it (0 at invalid pixels).
    pub fn dim(&self) -> BufferSlice {
        self.out.plane(10)
    }
}

/// The bindings of `clean` LP reads.
pub fn lp_inputs(s: &GpuStats) -> LpInputs {
    let (feat, var) = super::wlr::features(s);
    LpInputs {
        feat,
        var,
        color: std::array::from_fn(|c| s.plane(Layer::Color, c)),
        cvar: std::array::from_fn(|c| s.plane(Layer::ColorVariance, c)),
        spp: s.plane(Layer::Spp, 0),
    }
}

/// Records LP on sanitised statistics `clean` (colour, albedo, normal, depth,
/// their variances and spp). Outputs stay on the GPU in `planes`.
pub fn record_lp(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &LpPlanes,
    params: LpParams,
) -> Result<()> {
    let (w, h) = (clean.width, clean.height);
    let inp = lp_inputs(clean);
    batch.fill(planes.state.all(), 0);
    let reach = planes.reach.plane(0);
    for pass in 0..GRANULARITIES.len() {
        lp_reach::record(
            batch,
            precision,
            &params.push(w, h, pass),
            planes.state.plane(0),
            reach,
        )?;
        lp_centres::record(
            batch,
            precision,
            &params.push(w, h, pass),
            &inp,
            reach,
            planes.queue.plane(0),
            std::array::from_fn(|k| planes.state.plane(k)),
        )?;
    }
    lp_reach::record(
        batch,
        precision,
        &params.push(w, h, 0),
        planes.state.plane(0),
        reach,
    )?;
    lp_gather::record(
        batch,
        precision,
        &params.push(w, h, 0),
        &inp,
        reach,
        std::array::from_fn(|k| planes.state.plane(k)),
        planes.out.all(),
    )
}

/// Fraction of the pixels of a [`LpResult::centre_pass`] plane (or a crop of
/// it) that became centres.
pub fn centre_fraction(centre_pass: &[f32]) -> f64 {
    let n = centre_pass.len().max(1);
    centre_pass.iter().filter(|&&p| p > 0.0).count() as f64 / n as f64
}

/// What an LP run gives back on the host.
#[derive(Clone, Debug)]
pub struct LpResult {
    /// The reconstruction (§3.5: mean of the covering centres' predictions),
    /// clamped to ≥ 0.
    pub color: RgbImage,
    /// Estimated MSE per pixel and channel (LP-FEATNOISE):
    /// `E_i[ch] = mean_c max(ξ̂_c,ch, 0) + (Σ_j |ū[ch][j]| σ_ij)²` over the
    /// centres c covering i, `ū = mean_c u_c`, `σ_ij² = var(x_ij)` (≥ 0; 0
    /// at invalid pixels; see `reference::lp_gather::OUTPUTS`).
    pub error: RgbImage,
    /// ΔMSE per pixel and channel, `E_i·n_i^{-4/(d_i+4)}` (§3.5, §9.1), for
    /// sampling.
    pub dmse: RgbImage,
    /// Covering centres per pixel.
    pub coverage: Vec<f32>,
    /// Local dimension `d_i` per pixel (§9.1): mean `k_c` of the covering
    /// centres (0 at invalid pixels).
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
    let state0 = planes.state.download_plane::<f32>(0)?;
    Ok(LpResult::new(width, height, out, &state0))
}

/// The centre plane alone ([`LpResult::centre_pass`]: pass + 1 at centres,
/// else 0), for the centre fraction when no debug layers are asked for.
pub fn download_centre_pass(planes: &LpPlanes) -> Result<Vec<f32>> {
    planes.state.download_strided(0, 4)
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
    let push = params.push(w, h, 0);
    reference::lp_reach::lp_reach(&push, &state[0], &mut reach);
    reference::lp_gather::lp_gather(&push, &p, &reach, &state, &mut out);
    Ok(LpResult::new(w, h, out, &state[0]))
}
