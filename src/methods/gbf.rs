//! GBF: the G-buffer prefilter with world positions and SURE (spec §6), as a
//! sequence of kernels on sanitised statistics:
//!
//! ```text
//! gauss_rows       row sums of the position covariance (6) and the weights
//! gbf_prepare      S̃⁻¹ = (G_1.5(position_covariance) + εI)⁻¹ (column sums)
//! gbf_sure         SURE at h = 0, 0.4, …, 2.0 → h_opt
//! gauss_rows, gauss_smooth   hbar = G_1.5(h_opt)
//! gbf_pack         normal xyz + depth, albedo rgb and their variances → 4 vec4 planes
//! gbf_filter       all seven at hbar, written over the feature planes
//! gbf_pack, gbf_filter   GBF-SECOND: again, over the pixels with fewer
//!                  than `gbf.second_below` samples, features only
//! aos_nlm, copies  GBF-NLM: the albedo's NL-means (§5.2), clamped to 2
//!                  standard errors (`gbf.albedo_nlm`)
//! ```
//!
//! GBF-SECOND and GBF-NLM run in final reconstructions only
//! ([`GbfSettings::new`]).
//!
//! It runs before the method (spec §1) when [`Prefilter::resolve`] says
//! so: `auto` (the default) runs it for WLR, LP and APR when the input has
//! `position`, `position_variance` and `position_covariance`, and never
//! for `none` and AOS (AOS-NO-GBF).

use std::sync::Arc;

use super::stats::GpuStats;
use super::{Method, Prefilter};
use crate::error::{Error, Result};
use crate::gpu::{Batch, BufferSlice, GpuBuffer, GpuContext, PlaneSet, Precision};
use crate::image::{Layer, StatsImage};
use crate::kernels::{aos_nlm, gauss_smooth, gbf_filter, gbf_pack, gbf_prepare, gbf_sure};
use crate::reference;
use crate::reference::gbf::SMOOTH_SIGMA;
use crate::shared::{AosPush, GbfPush, SmoothPush, AOS_NLM_CLAMP};

/// The layers the prefilter reads besides the features.
pub const NEEDS: [Layer; 3] = [
    Layer::Position,
    Layer::PositionVariance,
    Layer::PositionCovariance,
];

/// Whether to prefilter an image with these layers before `method`
/// ([`Prefilter::resolve`] says what `prefilter` means for it);
/// [`Prefilter::On`] without the position layers is an error.
pub fn wanted(method: Method, prefilter: Prefilter, has: impl Fn(Layer) -> bool) -> Result<bool> {
    let all = NEEDS.iter().all(|&l| has(l));
    match prefilter.resolve(method) {
        Prefilter::Off => Ok(false),
        Prefilter::On if !all => Err(Error::BadData(
            "the G-buffer prefilter needs the position, position_variance and position_covariance layers"
                .into(),
        )),
        Prefilter::On => Ok(true),
        Prefilter::Auto => Ok(all),
    }
}

/// What the prefilter runs beyond the spec's one pass (ours), as a
/// reconstruction's options and pass ask.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GbfSettings {
    /// GBF-SECOND (`gbf.second_below`): pixels with fewer samples are
    /// filtered twice; 0: once, as the spec says.
    pub second_below: f32,
    /// GBF-NLM (`gbf.albedo_nlm`): the albedo's NL-means pass (§5.2,
    /// clamped to [`NLM_CLAMP_Z`](crate::shared::NLM_CLAMP_Z) standard
    /// errors) after the prefilter.
    pub albedo_nlm: bool,
}

impl GbfSettings {
    /// The spec's prefilter: one pass, nothing after it.
    pub const SPEC: GbfSettings = GbfSettings {
        second_below: 0.0,
        albedo_nlm: false,
    };

    /// The settings of `options` in a reconstruction of `pass` by
    /// `method`: an adaptive pass's (intermediate) runs the spec's
    /// prefilter, so the sample maps are the spec's; `gbf.albedo_nlm=auto`
    /// runs GBF-NLM for every method but LP, which loses with it on
    /// `glossy_cornell`.
    pub fn new(
        options: &crate::options::Options,
        method: Method,
        pass: super::Pass,
    ) -> Result<GbfSettings> {
        if pass != super::Pass::Final {
            return Ok(GbfSettings::SPEC);
        }
        let albedo_nlm = match options.get("gbf.albedo_nlm") {
            "auto" => method != Method::Lp,
            v => v == "on",
        };
        Ok(GbfSettings {
            second_below: options.value("gbf.second_below")?,
            albedo_nlm,
        })
    }

    /// The pixels beyond the first pass's window that the output reads:
    /// GBF-SECOND's window, then the NL-means' search and patch radii.
    pub fn extra_halo(&self) -> usize {
        let second = usize::from(self.second_below > 0.0) * reference::gbf::RADIUS;
        second
            + usize::from(self.albedo_nlm)
                * (reference::aos::NLM_SEARCH + reference::aos::NLM_PATCH)
    }
}

/// The feature planes in filtering (and packing) order.
const FEATURES: [(Layer, usize); 7] = super::wlr::FEATURE_PLANES;

/// GPU scratch: S̃⁻¹ (6), h_opt, hbar, and 16 planes that hold first the
/// row sums of the two smoothings, then the four packed vec4 planes.
#[derive(Debug)]
pub struct GbfPlanes {
    /// Planes of `width * height` f32: `S̃⁻¹` (6), `h_opt`, `hbar`, then
    /// 16 planes of scratch and packed features.
    pub set: PlaneSet,
    pixels: usize,
    /// What runs beyond the spec's one pass.
    pub settings: GbfSettings,
}

const INV: usize = 0;
const HOPT: usize = 6;
const HBAR: usize = 7;
const SCRATCH: usize = 8;
/// Planes of [`GbfPlanes`].
pub const PLANES: usize = SCRATCH + 16;

impl GbfPlanes {
    /// Allocates the scratch for a `width × height` image: [`PLANES`]
    /// planes, in `arena` (from its start, [`PlaneSet::view`]) when given:
    /// nothing of it is needed once the prefilter has written its outputs.
    pub fn new(
        ctx: &Arc<GpuContext>,
        width: usize,
        height: usize,
        arena: Option<&Arc<GpuBuffer>>,
        settings: GbfSettings,
    ) -> Result<GbfPlanes> {
        let n = width * height;
        let set = match arena {
            Some(a) => PlaneSet::view(a, 0, n, PLANES)?,
            None => PlaneSet::new(ctx, "gbf", n, PLANES)?,
        };
        Ok(GbfPlanes {
            set,
            pixels: n,
            settings,
        })
    }

    /// `h_opt` and `hbar` (debug).
    pub fn h_maps(&self) -> (BufferSlice, BufferSlice) {
        (self.set.plane(HOPT), self.set.plane(HBAR))
    }

    /// Rows `[first, end)` of packed vec4 plane `k` (0..4), a `width`-pixel
    /// image: the plane spans the four scalar planes from `SCRATCH + 4k`,
    /// whose strides hold at least `16 × pixels` bytes.
    fn packed(&self, k: usize, width: usize, (first, end): (u32, u32)) -> Result<BufferSlice> {
        let plane = self.set.plane(SCRATCH + 4 * k);
        let whole = self.set.all();
        let row = 16 * width as u64;
        debug_assert!(end as u64 * row <= 16 * self.pixels as u64);
        whole.sub(
            plane.offset() - whole.offset() + first as u64 * row,
            (end - first) as u64 * row,
        )
    }
}

/// Rows per chunk of `gbf_pack` and `gbf_filter` for a `width`-pixel image
/// whose packed bindings may not exceed `max_binding` bytes: a multiple of 16
/// (`gbf_filter` works on blocks of 2 rows, grouped by 8) such that a chunk
/// and 8 rows of halo on each side fit (the filter reads 3).
/// The whole image, `height`, when it fits in one.
fn chunk_rows(width: usize, height: usize, max_binding: u64) -> Result<u32> {
    let row = 16 * width as u64;
    if height as u64 * row <= max_binding {
        return Ok(height as u32);
    }
    let rows = (max_binding / row).saturating_sub(16) / 16 * 16;
    if rows == 0 {
        return Err(Error::Limit(format!(
            "the G-buffer prefilter needs {} bytes per binding for 32 rows of a {width}-pixel \
             image; maxStorageBufferRange is {max_binding}",
            32 * row
        )));
    }
    Ok(rows as u32)
}

fn smooth_push(w: usize, h: usize) -> SmoothPush {
    SmoothPush {
        width: w as u32,
        height: h as u32,
        radius: gauss_smooth::radius(SMOOTH_SIGMA),
        sigma: SMOOTH_SIGMA,
        ..Default::default()
    }
}

/// Records the prefilter on sanitised statistics `clean` (which must hold
/// the position layers and normal, albedo, depth with their variances) and
/// replaces its feature planes with the filtered ones.
pub fn record_gbf(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &GbfPlanes,
) -> Result<()> {
    let limit = batch.context().info.max_storage_buffer_range as u64;
    record_gbf_chunked(batch, precision, clean, planes, limit)
}

/// [`record_gbf`] with the packed vec4 bindings of `gbf_pack` and
/// `gbf_filter` limited to `max_binding` bytes: above that the image is
/// packed, then filtered, in chunks of rows (`chunk_rows`); every chunk
/// is packed before any is filtered, since the filter writes over the
/// feature planes the packing reads. The output does not depend on the
/// chunks (tested).
pub fn record_gbf_chunked(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &GbfPlanes,
    max_binding: u64,
) -> Result<()> {
    let (w, h) = (clean.width as u32, clean.height as u32);
    let p = |i: usize| planes.set.plane(i);
    let spp = clean.plane(Layer::Spp, 0);
    let pos: [BufferSlice; 3] = std::array::from_fn(|k| clean.plane(Layer::Position, k));
    let pos_var: [BufferSlice; 3] =
        std::array::from_fn(|k| clean.plane(Layer::PositionVariance, k));
    let cov: [BufferSlice; 6] = std::array::from_fn(|k| clean.plane(Layer::PositionCovariance, k));
    let inv: [BufferSlice; 6] = std::array::from_fn(|k| p(INV + k));
    let scratch: [BufferSlice; 7] = std::array::from_fn(|k| p(SCRATCH + k));
    gbf_prepare::record(batch, precision, w, h, cov, pos, spp, scratch, inv)?;
    gbf_sure::record(batch, precision, w, h, pos, pos_var, inv, spp, p(HOPT))?;
    gauss_smooth::record(
        batch,
        precision,
        w,
        h,
        SMOOTH_SIGMA,
        p(HOPT),
        spp,
        [scratch[0], scratch[1]],
        p(HBAR),
    )?;
    let (feat, var) = super::wlr::features(clean);
    let chunk = chunk_rows(clean.width, clean.height, max_binding)?;
    let packed = |rows: (u32, u32)| -> Result<[BufferSlice; 4]> {
        Ok([
            planes.packed(0, clean.width, rows)?,
            planes.packed(1, clean.width, rows)?,
            planes.packed(2, clean.width, rows)?,
            planes.packed(3, clean.width, rows)?,
        ])
    };
    let chunks: Vec<(u32, u32)> = (0..h)
        .step_by(chunk as usize)
        .map(|r0| (r0, (r0 + chunk).min(h)))
        .collect();
    // gbf_pack reads its inputs as whole vec4s (PACK-QUADS; `feat` and
    // `var` are bound so by wlr::features).
    let spp_quads = clean.plane_quads(Layer::Spp, 0);
    let out: [BufferSlice; 14] = std::array::from_fn(|k| if k < 7 { feat[k] } else { var[k - 7] });
    // GBF-SECOND: the same weights again, over the first pass's output.
    let passes: &[f32] = if planes.settings.second_below > 0.0 {
        &[0.0, planes.settings.second_below]
    } else {
        &[0.0]
    };
    for &second_below in passes {
        for &rows in &chunks {
            gbf_pack::record(
                batch,
                precision,
                w,
                h,
                rows,
                feat,
                var,
                spp_quads,
                packed(rows)?,
            )?;
        }
        for &(r0, r1) in &chunks {
            let halo = (r0.saturating_sub(8), (r1 + 8).min(h));
            gbf_filter::record(
                batch,
                precision,
                w,
                h,
                (r0, r1),
                halo.0,
                pos,
                inv,
                p(HBAR),
                packed(halo)?,
                out,
                second_below,
            )?;
        }
    }
    if planes.settings.albedo_nlm {
        record_albedo_nlm(batch, precision, clean, planes)?;
    }
    Ok(())
}

/// GBF-NLM: AOS's NL-means (§5.2, `aos_nlm`) of the prefiltered albedo,
/// clamped ([`AOS_NLM_CLAMP`]), into the scratch planes, then copied over
/// the albedo and its variance.
fn record_albedo_nlm(
    batch: &mut Batch,
    precision: Precision,
    clean: &GpuStats,
    planes: &GbfPlanes,
) -> Result<()> {
    let (w, h) = (clean.width, clean.height);
    let stride = planes.set.stride;
    let bytes = 5 * stride + 4 * (w * h) as u64;
    let limit = batch.context().info.max_storage_buffer_range as u64;
    if bytes > limit {
        return Err(Error::Limit(format!(
            "the prefilter's albedo NL-means (gbf.albedo_nlm) binds {bytes} bytes for a {w}x{h} \
             image; maxStorageBufferRange is {limit} (tile the image, or gbf.albedo_nlm=off)"
        )));
    }
    let albedo = Layer::Albedo;
    let vlayer = albedo.variance().expect("albedo has a variance layer");
    let g: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(albedo, c));
    let vg: [BufferSlice; 3] = std::array::from_fn(|c| clean.plane(vlayer, c));
    let push = AosPush {
        width: w as u32,
        height: h as u32,
        channels: 3,
        flags: AOS_NLM_CLAMP,
        stride: (stride / 4) as u32,
        ..Default::default()
    };
    let first = planes.set.plane(SCRATCH);
    let dst = planes
        .set
        .all()
        .sub(first.offset() - planes.set.all().offset(), bytes)?;
    aos_nlm::record(
        batch,
        precision,
        &push,
        g,
        vg,
        clean.plane(Layer::Spp, 0),
        dst,
    )?;
    for c in 0..3 {
        batch.copy(planes.set.plane(SCRATCH + c), g[c]);
        batch.copy(planes.set.plane(SCRATCH + 3 + c), vg[c]);
    }
    Ok(())
}

/// What a CPU run leaves for debugging: `h_opt` and `hbar` per pixel.
#[derive(Clone, Debug)]
pub struct GbfMaps {
    /// `h_opt` per pixel (§6.2 step 7): one of 0, 0.4, …, 2.0; 0 for an invalid pixel.
    pub h_opt: Vec<f32>,
    /// `hbar = G_1.5(h_opt)` per pixel (§6.2 step 8), a continuous bandwidth.
    pub hbar: Vec<f32>,
}

/// The CPU path: the scalar twins in the order of [`record_gbf`], on
/// sanitised statistics, in place, with `settings` as
/// [`GbfPlanes::settings`].
pub fn run_cpu(clean: &mut StatsImage, settings: GbfSettings) -> Result<GbfMaps> {
    let second_below = settings.second_below;
    for l in NEEDS {
        if !clean.has(l) {
            return Err(Error::BadData(format!(
                "the G-buffer prefilter needs the {} layer",
                l.name()
            )));
        }
    }
    let (w, h) = (clean.width, clean.height);
    let n = w * h;
    let spp = clean.get(Layer::Spp).unwrap()[0].clone();
    let smooth = |map: &[f32]| {
        let mut out = vec![0.0f32; n];
        reference::gauss_smooth::smooth(&smooth_push(w, h), map, &spp, &mut out);
        out
    };
    let pos = clean.get(Layer::Position).unwrap();
    let pos_var = clean.get(Layer::PositionVariance).unwrap();
    let push = GbfPush {
        width: w as u32,
        height: h as u32,
        ..Default::default()
    };
    let pos_r: [&[f32]; 3] = std::array::from_fn(|k| pos[k].as_slice());
    let cov = clean.get(Layer::PositionCovariance).unwrap();
    let inv = reference::gbf_prepare::prepare(
        w,
        h,
        std::array::from_fn(|k| cov[k].as_slice()),
        pos_r,
        &spp,
    );
    let inv_r: [&[f32]; 6] = std::array::from_fn(|k| inv[k].as_slice());
    let mut h_opt = vec![0.0f32; n];
    reference::gbf_sure::gbf_sure(
        &push,
        pos_r,
        std::array::from_fn(|k| pos_var[k].as_slice()),
        inv_r,
        &spp,
        &mut h_opt,
    );
    let hbar = smooth(&h_opt);
    let get = |l: Layer, c: usize| clean.get(l).map(|p| p[c].as_slice());
    let feat: [&[f32]; 7] = std::array::from_fn(|j| get(FEATURES[j].0, FEATURES[j].1).unwrap());
    let var: [&[f32]; 7] = std::array::from_fn(|j| {
        let (l, c) = FEATURES[j];
        get(l.variance().unwrap(), c).unwrap()
    });
    let packed = reference::gbf_pack::gbf_pack(feat, var, &spp);
    let mut out = vec![vec![0.0f32; n]; 14];
    reference::gbf_filter::gbf_filter(
        &push,
        pos_r,
        inv_r,
        &spp,
        &hbar,
        std::array::from_fn(|k| packed[k].as_slice()),
        &mut out,
    );
    if second_below > 0.0 {
        let packed = reference::gbf_pack::gbf_pack(
            std::array::from_fn(|j| out[j].as_slice()),
            std::array::from_fn(|j| out[7 + j].as_slice()),
            &spp,
        );
        let mut again = vec![vec![0.0f32; n]; 14];
        reference::gbf_filter::gbf_filter(
            &GbfPush {
                second_below,
                ..push
            },
            pos_r,
            inv_r,
            &spp,
            &hbar,
            std::array::from_fn(|k| packed[k].as_slice()),
            &mut again,
        );
        out = again;
    }
    let mut out = out.into_iter();
    for (l, c) in FEATURES {
        clean.get_mut(l).unwrap()[c] = out.next().unwrap();
    }
    for (l, c) in FEATURES {
        clean.get_mut(l.variance().unwrap()).unwrap()[c] = out.next().unwrap();
    }
    if settings.albedo_nlm {
        let vlayer = Layer::Albedo.variance().unwrap();
        let push = AosPush {
            width: w as u32,
            height: h as u32,
            channels: 3,
            flags: AOS_NLM_CLAMP,
            ..Default::default()
        };
        let g = clean.get(Layer::Albedo).unwrap();
        let vg = clean.get(vlayer).unwrap();
        let mut out = reference::aos_nlm::aos_nlm(
            &push,
            &[&g[0], &g[1], &g[2]],
            &[&vg[0], &vg[1], &vg[2]],
            &spp,
        )
        .into_iter();
        for c in 0..3 {
            clean.get_mut(Layer::Albedo).unwrap()[c] = out.next().unwrap();
        }
        for c in 0..3 {
            clean.get_mut(vlayer).unwrap()[c] = out.next().unwrap();
        }
    }
    Ok(GbfMaps { h_opt, hbar })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::methods::Pass;
    use crate::options::Options;

    fn settings(opts: &[&str], method: Method, pass: Pass) -> GbfSettings {
        GbfSettings::new(&Options::parse(opts).unwrap(), method, pass).unwrap()
    }

    /// `gbf.albedo_nlm=auto` is on for every method but LP, `on` and `off`
    /// override it, and an intermediate pass runs the spec's prefilter
    /// whatever the options say.
    #[test]
    fn albedo_nlm_auto_rule_and_intermediate_passes() {
        for m in [Method::Wlr, Method::Apr, Method::Aos, Method::Auto] {
            assert!(settings(&[], m, Pass::Final).albedo_nlm, "{m:?}");
        }
        assert!(!settings(&[], Method::Lp, Pass::Final).albedo_nlm);
        assert!(settings(&["gbf.albedo_nlm=on"], Method::Lp, Pass::Final).albedo_nlm);
        assert!(!settings(&["gbf.albedo_nlm=off"], Method::Wlr, Pass::Final).albedo_nlm);
        for m in [Method::Wlr, Method::Lp] {
            let s = settings(
                &["gbf.albedo_nlm=on", "gbf.second_below=8"],
                m,
                Pass::Intermediate,
            );
            assert_eq!(s, GbfSettings::SPEC, "{m:?}");
            assert_eq!(s.extra_halo(), 0);
        }
        let on = settings(
            &["gbf.albedo_nlm=on", "gbf.second_below=0"],
            Method::Wlr,
            Pass::Final,
        );
        assert_eq!(
            on.extra_halo(),
            reference::aos::NLM_SEARCH + reference::aos::NLM_PATCH
        );
    }
}
