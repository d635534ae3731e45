//! What the host, the GLSL kernels and their scalar twins share: push
//! constants, and the constants and layouts at the end of this module.
//!
//! Each is `#[repr(C)]` + [`bytemuck::Pod`] and mirrors one `push_constant`
//! block in `spirv/` (named in its doc). Each kernel's declared push size
//! is checked against its block's in the SPIR-V by reflection when its
//! pipeline is made (`gpu::reflect`, `tests/reflect.rs`); member offsets
//! are not checked: both sides follow from the members' order and types.

use bytemuck::{Pod, Zeroable};

/// `spirv/finalize_stats.comp` and `spirv/finalize_covariance.comp`, block `Push`.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FinalizePush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// `finalize_stats`: the origin the channel was accumulated relative to,
    /// added back to the mean ([`crate::AccumLayout::position_origin`]); 0
    /// for every other channel. Unused by `finalize_covariance` (its `_pad`).
    pub origin: f32,
}

/// `spirv/sanitize.comp`, `spirv/sanitize_low_spp.comp` and
/// `spirv/estimate_variance.comp`, block `Push` (spec §0.4).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SanitizePush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// 0: steps 1–2 (non-finite values, variance clamp); 1: step 3 (spp < 2);
    /// 2: step 4 (variance layer missing: MAD estimate).
    pub stage: u32,
    /// 1 if the channel has a variance plane (stage 0 only reads it then).
    pub has_var: u32,
    /// Margins of the image whose repairs are not counted, packed
    /// `left | top << 16` (a tile's halo, [`crate::methods::tiles`]: the
    /// counters then count each pixel of the whole image once); 0 counts all.
    pub skip_lo: u32,
    /// The `right | bottom << 16` margins (see `skip_lo`).
    pub skip_hi: u32,
    /// `sanitize_quads`: 1 when its outputs already hold its inputs (the
    /// in-place path of `methods::prepare`, which copies a channel before
    /// repairing it), so a quad that needs no repair is not written; 0
    /// writes every quad. Unused by the other kernels (0).
    pub in_place: u32,
}

impl SanitizePush {
    /// Whether a repair at pixel `(x, y)` is counted (outside the skipped
    /// margins).
    pub fn counts(&self, x: usize, y: usize) -> bool {
        let (l, t) = (self.skip_lo & 0xffff, self.skip_lo >> 16);
        let (r, b) = (self.skip_hi & 0xffff, self.skip_hi >> 16);
        x >= l as usize
            && y >= t as usize
            && x + (r as usize) < self.width as usize
            && y + (b as usize) < self.height as usize
    }
}

/// `spirv/tsvd_debug.comp`, block `Push` (spec §0.6).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TsvdPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Window radius R (5 or 9 in the spec; any value ≥ 1 works).
    pub radius: u32,
}

/// `spirv/wlr_fit.comp` and `spirv/wlr_final.comp`, block `Push` (spec §2).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct WlrPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Window radius: 9 in the final pass, 5 in intermediate passes (§2.3).
    pub radius: u32,
    /// Bit 0: `wlr.reject` on (§2.3 step 3). Bit 1: `wlr.outlier_weight`
    /// clamped (§2.3 step 2; off divides by nothing). Bit 2: `wlr.nonneg` on
    /// (§2.3 step 5). See [`WLR_REJECT`], [`WLR_OUTLIER_CLAMPED`], [`WLR_NONNEG`].
    pub options: u32,
    /// Rows of the ring that holds the centre state `wlr_fit` leaves for
    /// `wlr_final`: pixel (x, y) lives in its row `y mod ring_rows`
    /// (`spirv/lib/wlr.glsl`, `WLR_STATE_OUT`, `WLR_STATE_IN`). At least 1.
    pub ring_rows: u32,
    /// Unused (the block's `pad1`, `pad2`): rounds the block to 32 bytes; 0.
    pub _pad: [u32; 2],
}

/// [`WlrPush::options`] bit: confidence-interval rejection.
pub const WLR_REJECT: u32 = 1;
/// [`WlrPush::options`] bit: outlier weight `1/max(vbar, 1)`.
pub const WLR_OUTLIER_CLAMPED: u32 = 2;
/// [`WlrPush::options`] bit: positive-weight fallback.
pub const WLR_NONNEG: u32 = 4;
/// The spec's defaults: all three on.
pub const WLR_DEFAULT_OPTIONS: u32 = WLR_REJECT | WLR_OUTLIER_CLAMPED | WLR_NONNEG;
/// [`WlrPush::options`] bit: `wlr_fit` does not write the `b_j` planes and
/// `wlr_final` not the flags plane (no debug layers are read back).
pub const WLR_SKIP_DEBUG: u32 = 8;
/// [`WlrPush::options`] bit: `wlr_final` does not write the MSE plane (no
/// error download, sample map or debug layers read it).
pub const WLR_SKIP_MSE: u32 = 16;

/// `spirv/gauss_smooth.comp`, block `Push` (spec §0.5 Gaussian map smoothing).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SmoothPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// `ceil(3σ)`.
    pub radius: u32,
    /// Gaussian standard deviation σ in pixels (spec §0.5): 1 for WLR's
    /// `h_opt` map, 1.5 for GBF's, `sampling.smooth` (σs, §9.1) for the
    /// sample map; `<= 0` is the identity on valid pixels.
    pub sigma: f32,
    /// `gauss_rows`: how many of its six planes to smooth (1..=6); unused
    /// by the other kernels.
    pub count: u32,
    /// Unused (the block's `pad1`, `pad2`): rounds the block to 32 bytes; 0.
    pub _pad: [u32; 2],
}

/// `spirv/auto_score.comp`, `spirv/auto_dis.comp` and
/// `spirv/auto_blend.comp`, block `Push` (`--method auto`, AUTO-BLEND).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct AutoPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// The number of members (3 or 4; `auto_dis`, `auto_blend`).
    pub members: u32,
    /// The member this dispatch blends (`auto_blend`; 0 reads no sums).
    pub member: u32,
    /// 1 on `auto_blend`'s last dispatch, which writes the outputs.
    pub last: u32,
    /// Unused (the block's `pad0`, `pad1`): rounds the block to 32 bytes; 0.
    pub _pad: [u32; 2],
}

/// The most members `auto_dis` and `auto_blend` take.
pub const AUTO_MAX_MEMBERS: usize = 4;
/// The most disagreement maps (pairs of [`AUTO_MAX_MEMBERS`] members).
pub const AUTO_MAX_PAIRS: usize = 6;
/// The planes `auto_blend` carries between its dispatches: the base colour,
/// the weighted differences, the error roots (three each) and the weights'
/// sum.
pub const AUTO_SUMS: usize = 10;

/// The pairs `(a, b)`, `a < b`, of `members` members in the order of
/// `auto_dis`'s maps: `(0, 1), (0, 2), …, (0, n − 1), (1, 2), …`.
pub fn auto_pairs(members: usize) -> Vec<(usize, usize)> {
    (0..members)
        .flat_map(|a| (a + 1..members).map(move |b| (a, b)))
        .collect()
}
/// The smallest smoothed score `auto_blend` divides by.
pub const AUTO_SCORE_FLOOR: f64 = 1e-12;
/// The value `auto_score` and `auto_dis` write for a non-finite one.
pub const AUTO_SCORE_MAX: f32 = 1e30;

/// `spirv/peak_fma.comp` and `spirv/peak_copy.comp`, block `Push`: the
/// device-peak micro-kernels of `mcdenoise bench` (issue #13).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PeakPush {
    /// Invocations per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// `peak_fma`: rounds of eight real4 FMAs per invocation (unused by
    /// `peak_copy`).
    pub iterations: u32,
}

/// `spirv/spp_total.comp`, block `Push`: the image's sample total
/// (APR-COUNT-CAP).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SppTotalPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Unused (the block's `pad0`): rounds the block to 16 bytes; 0.
    pub _pad: u32,
}

/// `spirv/channel_mean.comp`, block `Push`: mean of three planes (vbar, grey).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ChannelMeanPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Unused (the block's `pad0`): rounds the block to 16 bytes; 0.
    pub _pad: u32,
}

/// `spirv/lp_centres.comp`, `spirv/lp_reach.comp` and `spirv/lp_gather.comp`,
/// block `Push` (spec §3).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LpPush {
    /// Image size (the centre kernel runs on the candidate grid
    /// `ceil(width/g) × ceil(height/g)`; its `row0` counts grid rows).
    pub width: u32,
    /// Image height in pixels (see `width`).
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Granularity `g` of this pass (19, 9, 4, 2, 1; §3.5). Centre kernel only.
    pub granularity: u32,
    /// Index of this pass (0..5); stored as `pass + 1` in the centre map.
    pub pass: u32,
    /// Bit 0: [`LP_VARSUB`] (`lp.error_mode = varsub`, `s = 1`, §3.4);
    /// bit 4: [`LP_CENTRE_TEST`]; bit 5: [`LP_PIXEL_TEST`]; bit 6:
    /// [`LP_OUTLIER_W`]; bits 1..3: the gather's `LP_SKIP_*`.
    pub options: u32,
    /// `lp_gather` only: f32 values from one output plane to the next in its
    /// packed output binding.
    pub out_stride: u32,
    /// `lp_select` and `lp_reach` (which computes only the candidates'
    /// columns): the candidate grid's phase `(φx, φy)` packed as
    /// `φx | φy << 16`, each `< g`: the candidates are the pixels
    /// `(φx + g·gx, φy + g·gy)`. 0 for a whole image; a tile whose first
    /// pixel is `(ox, oy)` of the image uses `φ = (−o) mod g`, so that its
    /// candidates are the image's (spec §3.5: `px mod g = 0` in image
    /// coordinates; see [`LpPush::phase_for`]).
    pub phase: u32,
    /// Rows of the ring that holds the state planes 1..8 and the `lp_reach`
    /// planes: pixel row `y` lives at ring row `y mod ring_rows` (state plane
    /// 0, the centre map, is whole). 0 = the image's height (no ring).
    /// `record_lp` runs the passes as a wavefront over the rows, so a row's
    /// state is dead `ring_rows` rows after it was made
    /// (`methods::lp`, LP-RING).
    pub ring_rows: u32,
}

impl LpPush {
    /// Rows the ring planes hold: [`LpPush::ring_rows`], 0 read as the
    /// image's height, at most the height.
    pub fn ring_len(&self) -> u32 {
        match self.ring_rows {
            0 => self.height,
            r => r.min(self.height),
        }
    }

    /// The candidate grid of this pass (granularity `g`, 0 read as 1):
    /// `ceil((width−φx)/g) × ceil((height−φy)/g)`, cell `(gx, gy)` ↔ pixel
    /// `(φx + g·gx, φy + g·gy)`. `lp_centres` runs one invocation per cell.
    pub fn centre_grid(&self) -> (u32, u32) {
        let g = self.granularity.max(1);
        let (fx, fy) = self.phase_xy();
        (
            self.width.saturating_sub(fx).div_ceil(g),
            self.height.saturating_sub(fy).div_ceil(g),
        )
    }

    /// `(φx, φy)` of [`LpPush::phase`].
    pub fn phase_xy(&self) -> (u32, u32) {
        (self.phase & 0xffff, self.phase >> 16)
    }

    /// The packed phase for granularity `g` of a tile whose pixel `(0, 0)`
    /// is pixel `origin` of the image.
    pub fn phase_for(g: u32, origin: (u32, u32)) -> u32 {
        let g = g.max(1);
        let f = |o: u32| (g - o % g) % g;
        f(origin.0) | f(origin.1) << 16
    }
}

/// `spirv/apr_block.comp` and `spirv/apr_gather.comp`, block `Push` (spec §4).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct AprPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers (grid rows of the centre
    /// grid in `apr_block`'s sparse mode).
    pub row0: u32,
    /// `apr_block`: the colour channel of the blocks (0..3).
    pub channel: u32,
    /// `apr_block`: 0 = the sparse centres' grid, 1 = extra centres (COVER)
    /// selected into a queue, one invocation per pixel, 2 = their fits, one
    /// invocation per queued pixel (set by `apr_block::record`).
    pub mode: u32,
    /// 1 on the last stage: no `β_s`; `apr_gather` writes the final planes.
    pub last: u32,
    /// Bits: [`APR_VIS`], [`APR_CLAMPED`], [`APR_PIXEL_TEST`],
    /// [`APR_COUNT_CAP`].
    pub flags: u32,
    /// f32 values from one plane to the next in the packed bindings (and
    /// from one ring slot to the next in the temporal window's).
    pub stride: u32,
    /// `apr_block` with [`APR_TEMPORAL`]: the window's frames `t−2..t+2`
    /// (index k = 0..4), bit k set for a present frame, its ring slot at
    /// bits `8 + 4k` ([`apr_window`]).
    pub window: u32,
}

/// [`AprPush::window`] of the frames `t−2..t+2` with these ring slots
/// (`None`: outside the sequence).
pub fn apr_window(slots: [Option<u32>; 5]) -> u32 {
    slots.iter().enumerate().fold(0, |w, (k, s)| match s {
        Some(s) => {
            assert!(*s < 16, "a ring slot is 4 bits");
            w | 1 << k | s << (8 + 4 * k)
        }
        None => w,
    })
}

/// [`AprPush::flags`] bit (`apr_block`, `apr_gather`): the temporal
/// window of spec §10.2 (APR-TEMPORAL-COLUMNS, 3D-KERNEL, SLICE).
pub const APR_TEMPORAL: u32 = 16;
/// `spp_total` words per ring slot of the temporal window's totals (one
/// slot per storage-buffer offset alignment).
pub const APR_SPPT_SLOT: usize = 64;

/// [`AprPush::flags`] bit: the visibility plane is bound (else a zero
/// feature).
pub const APR_VIS: u32 = 1;
/// [`AprPush::flags`] bit (`apr_block`): the block kernel is `K_h·o_i`,
/// `o_i = 1/max(v_i, 1)` (APR-OUTLIER-W).
pub const APR_CLAMPED: u32 = 2;
/// [`AprPush::flags`] bit (`apr_gather`): APR-PIXEL-TEST (`apr.pixel_test =
/// on`): a block whose prediction misses a pixel's own mean by more than
/// [`t_threshold3`](crate::reference::t_threshold3) standard errors does
/// not predict that pixel (ours, after LP-PIXEL-TEST).
pub const APR_PIXEL_TEST: u32 = 4;
/// [`AprPush::flags`] bit (`apr_block`, `apr_gather`): APR-COUNT-CAP
/// (`apr.count_cap = on`): the interval test takes a pixel with more than
/// twice the image's mean count at the variance it would have with twice
/// the mean (ours).
pub const APR_COUNT_CAP: u32 = 8;

/// [`LpPush::options`] bit: subtract the test pixel's variance (LP-VARSUB, `s = 1`).
pub const LP_VARSUB: u32 = 1;
/// [`LpPush::options`] bit, `lp_gather`: do not write the error planes (no
/// one reads them back).
pub const LP_SKIP_ERROR: u32 = 2;
/// [`LpPush::options`] bit, `lp_gather`: do not write the ΔMSE planes (no
/// sample map and no debug layers).
pub const LP_SKIP_DMSE: u32 = 4;
/// [`LpPush::options`] bit, `lp_gather`: do not write the coverage plane
/// (no debug layers).
pub const LP_SKIP_COVERAGE: u32 = 8;
/// [`LpPush::options`] bit: LP-CENTRE-TEST (`lp.centre_test = on`): a window
/// whose model misses its own centre by more than 3 standard errors counts
/// that miss as the error of every pixel of the window (§3.4, ours).
pub const LP_CENTRE_TEST: u32 = 16;
/// [`LpPush::options`] bit, `lp_gather`: LP-PIXEL-TEST (`lp.pixel_test =
/// on`): a centre whose prediction misses a pixel's own mean by more than
/// [`t_threshold3`](crate::reference::t_threshold3) standard errors does
/// not predict that pixel (§3.5, ours).
pub const LP_PIXEL_TEST: u32 = 32;
/// [`LpPush::options`] bit: LP-OUTLIER-W (`lp.outlier_weight = clamped`):
/// pixel i's row in centre c's fit has weight `1/max(vbar_i / max(vbar_c,
/// 1), 1)`, WLR's OUTLIER-W in the centre's noise (§3.3, ours).
pub const LP_OUTLIER_W: u32 = 64;

/// Index of the values of one LP centre in its 36-float state, written by
/// `spirv/lp_centres.comp` and read by `spirv/lp_gather.comp` (9 vec4
/// planes: value `s` of pixel `q` at plane `s/4`, element `4q + s%4` for plane
/// 0, the centre map; planes 1..8 are rings of rows, [`LpPush::ring_rows`]).
pub struct LpStateLayout;
impl LpStateLayout {
    /// `pass + 1` of the pass that created the centre; 0 = not a centre.
    pub const PASS: usize = 0;
    /// `r_opt` (§3.4).
    pub const R_OPT: usize = 1;
    /// TSVD rank `k_c`.
    pub const K: usize = 2;
    /// `β_c[ch][0]`, the prediction at the centre, R G B.
    pub const BETA0: usize = 3;
    /// `ξ̂_c,ch(r_opt)`, R G B.
    pub const XI: usize = 6;
    /// `u[ch][j]` at `U + 9 ch + j`.
    pub const U: usize = 9;
    /// Values per centre.
    pub const LEN: usize = 36;
    /// vec4 planes.
    pub const PLANES: usize = 9;
}

/// `spirv/gbf_prepare.comp`, `spirv/gbf_sure.comp` and `spirv/gbf_filter.comp`,
/// block `Push` (spec §6).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GbfPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First grid row of the band this dispatch covers: an image row, but a
    /// block of 8 rows for `gbf_prepare` and of 2 for `gbf_filter`
    /// (register blocking, see their host files).
    pub row0: u32,
    /// `gbf_pack` and `gbf_filter`: the image row at which their packed
    /// vec4 bindings start (0 unless the image is filtered in row chunks,
    /// see `methods::gbf`); unused by the other kernels.
    pub base: u32,
    /// `gbf_filter`: 0 for the spec's pass (steps 9–10: features and
    /// variances); above 0, GBF-SECOND's second pass, which filters again
    /// only the pixels with fewer samples than this and writes their
    /// features, not their variances. Unused by the other kernels.
    pub second_below: f32,
}

/// `spirv/sample_priority.comp`, block `Push` (spec §9.1).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SamplePriorityPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Bits [`SAMPLE_E_IS_DMSE`] and [`SAMPLE_D_KFLAGS`].
    pub flags: u32,
    /// `ε` of the relative error `ΔMSE/(f̂² + ε)` (> 0; §9.1 table).
    pub eps: f32,
    /// Unused (the block's `pad0..pad2`): rounds the block to 32 bytes; 0.
    pub _pad: [u32; 3],
}

/// [`SamplePriorityPush::flags`] bit: the error planes already hold `ΔMSE`
/// (LP, §3.5): the factor `n^(-4/(d+4))` is skipped.
pub const SAMPLE_E_IS_DMSE: u32 = 1;
/// [`SamplePriorityPush::flags`] bit: the `d` plane is WLR's `kflags`
/// (`k + 16·flags`): `d = floor(value) mod 16`.
pub const SAMPLE_D_KFLAGS: u32 = 2;

/// `spirv/sample_reduce.comp` and `spirv/sample_scan.comp`, block `Push`
/// (spec §9.2): one level of the allocation's reduction / scan tree. Offsets
/// count u64 entries of the tree buffer.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SampleTreePush {
    /// Dispatch grid in invocations: `8·groups_x × 8·groups_y`.
    pub width: u32,
    /// Dispatch grid height in invocations (`8·groups_y`; see `width`).
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Kernel mode (see the `.comp` headers and [`crate::kernels::sample_reduce`]).
    pub mode: u32,
    /// Elements of this level (pixels at the leaf level).
    pub n: u32,
    /// Workgroups per grid row; block `b` is at `(b % groups_x, b / groups_x)`.
    pub groups_x: u32,
    /// First entry of this level's elements (inner levels).
    pub src_off: u32,
    /// First entry of this level's output.
    pub dst_off: u32,
    /// First entry of the parent level's exclusive offsets, or `u32::MAX`
    /// (`sample_scan` at the top level).
    pub par_off: u32,
    /// Entry of the global max (bits of max r, bit 32 = "a pixel is invalid").
    pub max_off: u32,
    /// Entry of `S = sum q`.
    pub s_off: u32,
    /// Entry of `U = sum u`.
    pub u_off: u32,
    /// Budget `T` of the pass that the map distributes (`sample_scan` leaf).
    pub budget: u32,
    /// Samples spread evenly over the pixels besides `budget` (by
    /// cumulative rounding in raster order: the uniform floor of
    /// [`crate::methods::sampling::floor_split`]).
    pub spread: u32,
    /// Unused (the block's `pad1..pad2`): rounds the block to 64 bytes; 0.
    pub _pad: [u32; 2],
}

/// `spirv/lib/outliers.glsl`, block `Push`: every kernel of the outlier stage
/// (`outlier_grey`, `outlier_rows`, `outlier_detect`, `outlier_median`,
/// `box_rows`, `outlier_weights`, `outlier_spread`; spec §4.4).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct OutlierPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Window radius: 14 for detection, 43 or 215 (OUTLIER-WIDE) for
    /// redistribution.
    pub radius: u32,
    /// `box_rows`: how many planes one dispatch sums over the valid pixels
    /// (2 or 4), plus [`BOX_COUNT_LAST`] when the fourth counts them instead
    /// (set by `kernels::box_rows::record`); `outlier_median`: 0, or
    /// [`OUTLIER_APPLY`] (set by `kernels::outlier_median`);
    /// `outlier_weights`: 0, [`WEIGHTS_NARROW`] or [`WEIGHTS_WIDE`];
    /// `outlier_detect`: 0, or [`DETECT_RIM`].
    pub mode: u32,
    /// Fewest valid neighbours a detection needs (OUTLIER-MIN-N).
    pub min_n: u32,
    /// Detection threshold in standard deviations (3).
    pub k_sigma: f32,
    /// DARK-WINDOW factor (1e-8).
    pub dark: f32,
    /// `outlier_weights`: OUTLIER-WIDE's fraction of the window's grey sum
    /// (mode [`WEIGHTS_NARROW`]).
    pub wide: f32,
}

/// [`OutlierPush::mode`] of `outlier_weights`: weigh the outliers whose
/// excess is at most [`OutlierPush::wide`] of their window's grey sum and
/// mark the others for the wide window (OUTLIER-WIDE; 0 weighs every one).
pub const WEIGHTS_NARROW: u32 = 1;

/// [`OutlierPush::mode`] of `outlier_detect`: OUTLIER-RIM (`outliers.rim=on`,
/// the default): for a pixel of one or two rare paths, a bright 8-neighbour
/// keeps it from detection only when it is a rare path with at least half
/// the pixel's excess, or a steady pixel with less (`DETECT_RIM` in
/// `spirv/lib/outliers.glsl`).
pub const DETECT_RIM: u32 = 1;

/// [`OutlierPush::mode`] of `outlier_weights`: weigh only the outliers that
/// [`WEIGHTS_NARROW`] marked.
pub const WEIGHTS_WIDE: u32 = 2;

/// [`OutlierPush::mode`] flag of `box_rows`: the last plane counts the valid
/// pixels (its value is not read). The twin `reference::box_rows` counts when
/// it is set.
pub const BOX_COUNT_LAST: u32 = 8;

/// [`OutlierPush::mode`] of `outlier_median`'s second dispatch: write the
/// replacements it found into the statistics.
pub const OUTLIER_APPLY: u32 = 1;

/// `spirv/aos_nlm.comp`, `spirv/aos_space.comp` and `spirv/aos_fit.comp`,
/// block `Push` (spec §5).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct AosPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers, relative to `base_row`.
    pub row0: u32,
    /// Window radius R (9 final, 5 intermediate; `aos_space`, `aos_fit`).
    pub radius: u32,
    /// `aos_nlm`: channels of the buffer (1 or 3).
    pub channels: u32,
    /// `aos_fit`: bits [`AOS_SANDWICH`], [`AOS_BIAS_TEST`], [`AOS_IDENTITY`],
    /// [`AOS_OUTLIER_W`], [`AOS_RESIDUAL`], [`AOS_FEATNOISE`];
    /// `aos_nlm`: [`AOS_NLM_CLAMP`].
    pub flags: u32,
    /// The image row of the scratch buffer's first row: `aos_space` and
    /// `aos_fit` cover rows `base_row + row0 ..` and index the per-pixel
    /// projections from `base_row` (row bands bound the scratch's size).
    pub base_row: u32,
    /// f32 values from one plane to the next in the packed output binding
    /// (`aos_nlm`, `aos_fit`).
    pub stride: u32,
}

/// [`AosPush::flags`]: `aos.variance=sandwich` (AOS-VAR).
pub const AOS_SANDWICH: u32 = 1;
/// [`AosPush::flags`]: `aos.bias_test=on` (AOS-BIAS-TEST).
pub const AOS_BIAS_TEST: u32 = 2;
/// [`AosPush::flags`]: `aos.identity=on` (AOS-IDENTITY).
pub const AOS_IDENTITY: u32 = 4;
/// [`AosPush::flags`]: `aos.outlier_weight=clamped` (AOS-OUTLIER-W).
pub const AOS_OUTLIER_W: u32 = 8;
/// [`AosPush::flags`]: AOS-RESIDUAL (`aos.residual=on`).
pub const AOS_RESIDUAL: u32 = 16;
/// [`AosPush::flags`]: AOS-FEATNOISE (`aos.feature_noise=on`).
pub const AOS_FEATNOISE: u32 = 32;
/// [`AosPush::flags`]: AOS-IDENTITY-FLOOR (`aos.identity_floor=on`).
pub const AOS_IDENTITY_FLOOR: u32 = 64;
/// [`AosPush::flags`] (`aos_nlm`): each filtered channel is clamped to
/// [`NLM_CLAMP_Z`] of its input's standard errors around the input
/// (GBF-NLM, the prefilter's albedo pass).
pub const AOS_NLM_CLAMP: u32 = 128;
/// Standard errors around its input that [`AOS_NLM_CLAMP`] keeps a
/// filtered channel within.
pub const NLM_CLAMP_Z: f32 = 2.0;

// Constants the kernels and their scalar twins share (layouts and sizes that
// both the host dispatch and the twin must agree on). `src/kernels` reads
// them from here, never from `src/reference`.

/// APR's window radius and centre spacing: 29×29 blocks every 14 pixels
/// (spec §4.3).
pub const APR_RADIUS: usize = 14;
/// APR's design columns at order 3: the intercept, 8 features and the 9
/// non-constant monomials of `(u, v)` up to degree 3 (spec §4.1).
pub const APR_P: usize = 18;
/// APR's extra-block planes per channel (COVER, spec §4.3).
pub const APR_EXTRA_PLANES: usize = 4;
/// APR's output planes of the last stage: colour R G B, error R G B,
/// dimension, extra mask R G B.
pub const APR_OUTPUTS: usize = 10;
/// APR's output planes of an intermediate stage: `ŷ` R G B, `σ̂²` R G B.
pub const APR_STAGE_OUTPUTS: usize = 6;

/// f32 values per (block, channel) in APR's state buffer (13 vec4).
pub const APR_STATE: usize = 52;

/// APR's sparse centres' grid: `ceil(w/14) × ceil(h/14)`, cell `(gx, gy)` ↔
/// pixel `(14 gx, 14 gy)`.
pub fn apr_grid(w: usize, h: usize) -> (usize, usize) {
    (w.div_ceil(APR_RADIUS), h.div_ceil(APR_RADIUS))
}

/// AOS's feature dimension: `(px, py, dep, a_r, a_g, a_b, nrm_x, nrm_y,
/// nrm_z, vis)` (spec §5.3).
pub const AOS_D: usize = 10;
/// f32 values per pixel of AOS's local-space scratch: `P` row-major
/// (`P[m][j]` at `m·D + j`), then `k`.
pub const AOS_SPACE: usize = AOS_D * AOS_D + 1;
/// AOS's highest polynomial order (the order-5 fit shared by orders 1 and
/// 3, AOS-ONE-RIDGE).
pub const AOS_P_STAR: usize = 5;
/// Most columns of AOS's order-5 design: `1 + 5·D`.
pub const AOS_MAX_COLS: usize = 1 + AOS_P_STAR * AOS_D;
/// `aos_fit`'s output planes, in order: colour R G B (clamped ≥ 0), the
/// exported error (`MSE_c` plus AOS-FEATNOISE's term), the chosen order (0:
/// the input), rank `k`, `bias_1`, `var_1`, `bias_3`, `var_3`, `σ*²`,
/// `sd(bias_1)`, `sd(bias_3)`, `MSE_c` (the sample map's `E_i`).
pub const AOS_OUTPUTS: usize = 14;
/// Names of `aos_fit`'s debug planes 4..14 (spec §5.5).
pub const AOS_DEBUG_NAMES: [&str; 10] = [
    "aos_order",
    "aos_rank",
    "aos_bias1",
    "aos_var1",
    "aos_bias3",
    "aos_var3",
    "aos_sigma2",
    "aos_bias_sd1",
    "aos_bias_sd3",
    "aos_map_mse",
];

/// σ of the G-buffer prefilter's Gaussian smoothing of the `h` map and of
/// `S` (spec §6.2).
pub const GBF_SMOOTH_SIGMA: f32 = 1.5;

/// The radius of a Gaussian map smoothing of width `sigma` (spec §0.5:
/// `ceil(3σ)`, 0 for σ ≤ 0).
pub fn gaussian_radius(sigma: f64) -> usize {
    (3.0 * sigma).ceil().max(0.0) as usize
}

/// `sample_reduce` mode: leaf of the max tree, the max of the sanitised `r`
/// bits of valid pixels (bit 32 of the result set if some pixel is invalid,
/// `n = 0`).
pub const REDUCE_LEAF_MAX: u32 = 0;
/// `sample_reduce` mode: inner level of the max tree.
pub const REDUCE_MAX: u32 = 1;
/// `sample_reduce` mode: leaf of the sum of the quantised priorities `q_i` (`S`).
pub const REDUCE_LEAF_Q: u32 = 2;
/// `sample_reduce` mode: leaf of the sum of the shares `u_i = floor(2^32 q_i / S)` (`U`).
pub const REDUCE_LEAF_U: u32 = 3;
/// `sample_reduce` mode: inner level of a sum tree.
pub const REDUCE_SUM: u32 = 4;
/// `sample_scan` mode: exclusive offsets of the block sums `tree[src_off..]`,
/// written to `tree[dst_off..]`.
pub const SCAN_INNER: u32 = 0;
/// `sample_scan` mode: the leaf, `counts[i]` = its even share of `spread` plus
/// `floor(T P_i / U) − floor(T P_{i−1} / U)`.
pub const SCAN_LEAF: u32 = 1;
/// "No parent level" in [`SampleTreePush::par_off`].
pub const SCAN_NO_LEVEL: u32 = u32::MAX;

/// `spirv/lp_temporal.comp`, block `Push` (spec §10.1, the LP temporal
/// filter).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TemporalPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// [`TEMPORAL_RESET`], [`TEMPORAL_NO_SEARCH`] and [`TEMPORAL_MOTION`].
    pub flags: u32,
    /// The forgetting factor `λ` ([`TEMPORAL_LAMBDA`] by default).
    pub lambda: f32,
    /// `P₀₀` of a (re)initialised pixel: its intercept's variance per unit
    /// noise ([`TEMPORAL_RESET_P00`]; §10.1 has `1/δ`).
    pub p00: f32,
    /// `P₁₁` of a (re)initialised pixel: its slope's prior variance per unit
    /// noise ([`TEMPORAL_RESET_P11`]; §10.1 has `1/δ`).
    pub p11: f32,
    /// TEMPORAL-MISREG: the factor the method's error estimate is low by
    /// on average (its `MethodInfo::error_scale`); 0 reads as 1.
    pub error_scale: f32,
    /// TEMPORAL-TEST-SCALE: the factor on the method's error estimate in
    /// TEMPORAL-INFLATE's test (its `MethodInfo::inflate_scale`); 0 reads
    /// as 1.
    pub inflate_scale: f32,
}

/// `spirv/lp_smooth.comp`, block `Push` (TEMPORAL-SMOOTH, SMOOTH-SHORT).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TwoWayPush {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// Unused (the block's `pad0`): keeps the two informations in the
    /// block's second 16 bytes; 0.
    pub _pad0: u32,
    /// SMOOTH-SHORT: the information `1/P₀₀` the filter in frame order
    /// holds at a pixel that met no change since the sequence began
    /// ([`full_information`] of its frames).
    pub full_forward: f32,
    /// … and the filter in reverse order.
    pub full_backward: f32,
    /// Unused (the block's `pad1`, `pad2`): rounds the block to 32 bytes; 0.
    pub _pad: [u32; 2],
}

/// SMOOTH-SHORT: a direction whose information falls below this fraction
/// of its [`full_information`] has met a change (a restart, a discount),
/// and the other direction weighs at most as much as it.
pub const SMOOTH_SHORT: f32 = 0.9;

/// The information `1/P₀₀` of the LP temporal filter (§10.1, its slope
/// held at 0) after `frames` updates without a change test that
/// discounted the history: the first frame's `1/p00`, then `a ← λa + 1`
/// per frame, `λⁿ⁻¹/p00 + Σ_{j<n−1} λʲ`. 0 for no frames.
pub fn full_information(frames: u64, lambda: f64, p00: f64) -> f64 {
    if frames == 0 {
        return 0.0;
    }
    let m = (frames - 1) as f64;
    let decay = lambda.powf(m);
    let sum = if (1.0 - lambda).abs() < 1e-12 {
        m
    } else {
        (1.0 - decay) / (1.0 - lambda)
    };
    decay / p00 + sum
}

/// [`TemporalPush::flags`]: forget every pixel's history (a cut, or the
/// first frame): every pixel is reinitialised.
pub const TEMPORAL_RESET: u32 = 1;
/// [`TemporalPush::flags`]: no reprojection, pixel `i` continues its own
/// state (`j = i`) and is never reset by distance (§10.1's invariant).
pub const TEMPORAL_NO_SEARCH: u32 = 2;
/// [`TemporalPush::flags`]: the 7×7 search window is centred where the
/// coarse-to-fine motion search put each pixel (TEMPORAL-MOTION: the
/// bindings `mx`, `my` hold the offsets per pixel); without it, on the
/// pixel itself.
pub const TEMPORAL_MOTION: u32 = 4;
/// TEMPORAL-MOTION: pooled levels of the motion search's pyramids of
/// positions (1: half resolution, up to 4: a sixteenth), searched before
/// the full resolution (level 0).
pub const TEMPORAL_MOTION_LEVELS: usize = 4;
/// TEMPORAL-MOTION: the search radius at every level (5×5); with
/// [`TEMPORAL_MOTION_LEVELS`] and level 0 it reaches
/// `2 + 2·(2 + 2·(2 + 2·(2 + 2·2)))` = 62 pixels, and the 7×7 window
/// around that 3 more.
pub const TEMPORAL_MOTION_RADIUS: i32 = 2;
/// The forgetting factor `λ` of §10.1 `[LP §6]`.
pub const TEMPORAL_LAMBDA: f32 = 0.98;
/// TEMPORAL-PRIOR: `P₀₀` of a reinitialised pixel. The frame that starts
/// a history counts as one observation, where §10.1's `P = I/δ`
/// (`δ = 0.001`, `[LP §7]`) makes it a prior the next frame overrides.
pub const TEMPORAL_RESET_P00: f32 = 1.0;
/// TEMPORAL-PRIOR: `P₁₁` of a reinitialised pixel, the slope's prior
/// variance per unit noise per frame² (§10.1: `1/δ`).
pub const TEMPORAL_RESET_P11: f32 = 0.0;
/// Radius of the reprojection search: a 7×7 window (SEARCH-7).
pub const TEMPORAL_SEARCH: i32 = 3;
/// RESET: a match farther than this fraction of the viewing distance
/// reinitialises the pixel.
pub const TEMPORAL_RESET_REL: f64 = 0.01;
/// RESET: the floor of the viewing distance the threshold scales.
pub const TEMPORAL_DEPTH_FLOOR: f64 = 1e-3;
/// RESET-NOISE: the squared distance RESET allows grows by this many
/// times the sum of the pixel's mean-position variances: 3 standard
/// deviations of the difference of two independent means of that variance
/// (`9 · 2 · Σ var`).
pub const TEMPORAL_RESET_NOISE: f64 = 18.0;
/// TEMPORAL-SUBPIXEL: a neighbour of the reprojected pixel is on its
/// surface where their positions are within this many times RESET's
/// squared distance (twice the distance).
pub const TEMPORAL_SUBPIXEL_GATE: f64 = 4.0;
/// TEMPORAL-SUBPIXEL: the resampling offset's bound per axis, in pixels:
/// the reprojected pixel is the nearest in position, or nearly.
pub const TEMPORAL_SUBPIXEL_REACH: f64 = 0.5;
/// TEMPORAL-RIM: a window's brightest pixel excuses a history within the
/// window's colours where it is at least this many times as bright as the
/// pixel (R + G + B, the pixel's plus 0.01).
pub const TEMPORAL_RIM_CONTRAST: f64 = 8.0;
/// TEMPORAL-RIM: … and where its previous intercepts are within this
/// fraction of its colour (absolute differences and colour summed over
/// the channels).
pub const TEMPORAL_RIM_TOL: f64 = 0.25;
/// TEMPORAL-RIM: … and where the pixel's prediction (R + G + B) is at most
/// this fraction of the brightest pixel's colour: a pixel the light partly
/// covers, not one it covered and has left.
pub const TEMPORAL_RIM_HISTORY: f64 = 0.5;
/// Planes of the temporal state, per pixel: `β` per channel (intercept,
/// slope: R0 R1 G0 G1 B0 B1), `P` (`P00 P01 P11`), the position `W` (X Y Z)
/// and the valid flag (1 or 0).
pub const TEMPORAL_STATE: usize = 13;
/// The state plane of `P00` (the debug map `temporal_p00`).
pub const TEMPORAL_P00: usize = 6;
/// The state plane of the valid flag.
pub const TEMPORAL_VALID: usize = 12;
/// The debug plane `temporal_source`: the reprojection source's offset
/// from the window's centre (TEMPORAL-MOTION) `(dy + 3)·7 + (dx + 3)` in
/// 0..49, this value where the pixel was
/// reinitialised, [`TEMPORAL_SOURCE_NONE`] where it was passed through
/// (an invalid pixel or a non-finite colour).
pub const TEMPORAL_SOURCE_RESET: f32 = -1.0;
/// See [`TEMPORAL_SOURCE_RESET`].
pub const TEMPORAL_SOURCE_NONE: f32 = -2.0;

/// `spirv/temporal_motion.comp`, block `Push` (TEMPORAL-MOTION): one level
/// of the coarse-to-fine motion search.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MotionPush {
    /// The level's width in pixels.
    pub width: u32,
    /// Its height.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// 1 where the coarser level's offsets (`ox_c`, `oy_c`) centre the
    /// search; 0 at the coarsest level (centre 0).
    pub coarse: u32,
    /// The coarser level's width (its offsets' plane).
    pub coarse_width: u32,
    /// Its height.
    pub coarse_height: u32,
    /// The search radius ([`TEMPORAL_MOTION_RADIUS`]).
    pub radius: i32,
    /// Unused: 0.
    pub _pad: u32,
}

/// `spirv/pyramid_pool.comp` and `spirv/pyramid_merge.comp`, block `Push`
/// (the pyramid's low band, PYRAMID-LOWBAND), and
/// `spirv/sample_upsample.comp`'s (MAP-COARSE: `width × height` the fine
/// image, `other_*` the coarse one).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PyramidPush {
    /// Width in pixels of the image the dispatch covers (`pyramid_pool`:
    /// the coarse level; `pyramid_merge`: the fine one).
    pub width: u32,
    /// Its height.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// `pyramid_pool`: how the plane pools ([`PYRAMID_MEAN`],
    /// [`PYRAMID_VARIANCE`] or [`PYRAMID_COUNT`]); `pyramid_merge`: 0.
    pub kind: u32,
    /// The other level's width (`pyramid_pool`: the fine image's;
    /// `pyramid_merge`: the coarse one's).
    pub other_width: u32,
    /// The other level's height.
    pub other_height: u32,
    /// `pyramid_merge`: the ratio's `ε` ([`PYRAMID_EPS`]).
    pub eps: f32,
    /// Unused: 0.
    pub _pad: u32,
}

/// [`PyramidPush::kind`]: a mean, pooled weighted by the sample counts.
pub const PYRAMID_MEAN: u32 = 0;
/// [`PyramidPush::kind`]: the variance of a mean, pooled as `Σ n² v / N²`.
pub const PYRAMID_VARIANCE: u32 = 1;
/// [`PyramidPush::kind`]: the sample count, summed over the valid pixels.
pub const PYRAMID_COUNT: u32 = 2;
/// The `ε` of the low band's ratio `(up(c) + ε) / (L(f) + ε)`
/// (PYRAMID-LOWBAND).
pub const PYRAMID_EPS: f32 = 1e-3;

/// `spirv/input_blend.comp`, block `Push` (the input blend, INPUT-BLEND).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BlendPush {
    /// Width of the image in pixels.
    pub width: u32,
    /// Its height.
    pub height: u32,
    /// First row of the band this dispatch covers.
    pub row0: u32,
    /// The radius `r` of the window whose trimmed mean variance floors a
    /// pixel's: `V = max(v, trim_{2r+1}(v))`, the mean over the window
    /// without its `⌈n/10⌉` largest values, at most [`BLEND_TRIM_MAX`]
    /// (BLEND-TRIM).
    pub radius: u32,
    /// The weight `k` of the reconstruction's error estimate against the
    /// input's variance.
    pub k: f32,
    /// The radius `s` of the residual's window (BLEND-RESIDUAL): the
    /// reconstruction's error is read as at least the window's mean of
    /// `(f − y)² − v`, less `z` of its standard deviation; 0: not read.
    pub residual_radius: u32,
    /// The `z` of the residual's test.
    pub z: f32,
    /// Unused: 0.
    pub _pad: u32,
}

/// The `z` of the input blend's residual test (BLEND-RESIDUAL,
/// `blend.z`) for every method but AOS (BLEND-AOS: 0.7).
pub const BLEND_Z: f32 = 1.0;
/// The radius of the input blend's residual window (BLEND-RESIDUAL,
/// `blend.residual_radius`) for every method but AOS (BLEND-AOS: 4).
pub const BLEND_RESIDUAL_RADIUS: u32 = 3;
/// The most variances the input blend's variance window leaves out of its
/// mean: it drops its `⌈n/10⌉` largest, at most this many and never all
/// (BLEND-TRIM; mirrored as `BLEND_TRIM_MAX` in `spirv/input_blend.comp`).
pub const BLEND_TRIM_MAX: usize = 8;
