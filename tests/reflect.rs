//! Every compiled kernel (f32 and f64) is read by naga and agrees with the
//! bindings, push-constant size and workgroup size the Rust side declares.

use mcdenoise::gpu::reflect::{reflect, spirv};
use mcdenoise::gpu::KernelDecl;
use mcdenoise::gpu::{Access, Precision};
use mcdenoise::kernels::ALL as LIBRARY_KERNELS;

/// The library's kernels and the built-in renderer's.
fn all() -> impl Iterator<Item = &'static KernelDecl> {
    LIBRARY_KERNELS
        .iter()
        .chain(mcdenoise::render::KERNELS)
        .copied()
}

/// Kernels with no float arithmetic at all (the §9.2 allocation is exact
/// integer arithmetic, and so is the renderer's prefix sum of its counts):
/// their `_f64` variant is the same code.
const INTEGER_ONLY: &[&str] = &["sample_reduce", "sample_scan", "render_scan"];

/// Kernels that compute in f32 by design and never use `real`: the path
/// tracer (`src/render/`), LP's centre selection (it compares stored f32
/// reaches with distances) and the sample total (f32 counts rounded to
/// integers, APR-COUNT-CAP); their `_f64` variant is the same code.
const F32_ONLY: &[&str] = &[
    "render_trace",
    "render_features",
    "render_rays",
    "render_lights",
    "render_resolve",
    "lp_select",
    "spp_total",
];

/// Kernels that only move data (the bandwidth probe of `bench --peak`, the
/// G-buffer prefilter's and APR's packing, MAP-COARSE's upsampling): their
/// `_f64` variant is the same code.
const COPY_ONLY: &[&str] = &["peak_copy", "gbf_pack", "apr_pack", "sample_upsample"];

#[test]
fn every_kernel_matches_its_declaration() {
    for decl in all() {
        for p in [Precision::F32, Precision::F64] {
            let r = decl
                .check(p)
                .unwrap_or_else(|e| panic!("{}{}: {e}", decl.name, p.suffix()));
            // One workgroup per pixel for aos_fit (spec §5.4); the dispatch
            // counts invocations in x by THREADS per pixel.
            // outlier_median, outlier_weights and lp_centres run one
            // invocation per queued pixel.
            let wg = if decl.name == "aos_fit" {
                [mcdenoise::kernels::aos_fit::THREADS, 1, 1]
            } else if ["outlier_median", "outlier_weights"].contains(&decl.name) {
                [mcdenoise::kernels::outlier_median::GROUP, 1, 1]
            } else if decl.name == "lp_centres" {
                [mcdenoise::kernels::lp_centres::GROUP, 1, 1]
            } else if decl.name == "lp_reach" || decl.name == "lp_select" {
                // One row per workgroup row: any range of rows (LP-RING).
                [64, 1, 1]
            } else if [
                "render_trace",
                "render_features",
                "render_scan",
                "render_resolve",
            ]
            .contains(&decl.name)
            {
                // One invocation per sample, per block of pixels, per item.
                [64, 1, 1]
            } else {
                [8, 8, 1]
            };
            assert_eq!(r.workgroup_size, wg, "{}: workgroup", decl.name);
            assert!(r.shared_bytes <= 32 * 1024, "{}: shared memory", decl.name);
            // f32 variants use f64 only where the spec demands it (WLR §0.3) or our
            // decision AOS-F64 does (spirv/aos_fit.comp).
            if p == Precision::F32 {
                assert_eq!(
                    r.uses_f64,
                    decl.name.starts_with("wlr_") || decl.name == "aos_fit",
                    "{}: f64 use",
                    decl.name
                );
            } else {
                // The _f64 variant really computes in f64 (MC_F64 took effect).
                assert!(
                    r.uses_f64
                        || INTEGER_ONLY.contains(&decl.name)
                        || F32_ONLY.contains(&decl.name)
                        || COPY_ONLY.contains(&decl.name),
                    "{}_f64 has no f64 arithmetic",
                    decl.name
                );
            }
        }
    }
}

/// Every kernel runs on a device without 64-bit types: no f32 variant uses
/// 64-bit integers, and each that uses f64 (WLR's, `aos_fit`) has a `_dd`
/// variant that matches its declaration and uses neither.
#[test]
fn f32_variants_or_their_dd_twins_need_no_64bit_types() {
    for decl in all() {
        let r = decl.check(Precision::F32).unwrap();
        assert!(!r.uses_int64, "{}: 64-bit integers", decl.name);
        match mcdenoise::gpu::reflect::spirv_dd(decl.name) {
            Some(words) => {
                let dd = decl
                    .check_words(&format!("{}_dd", decl.name), words)
                    .unwrap_or_else(|e| panic!("{}_dd: {e}", decl.name));
                assert!(
                    !dd.uses_f64 && !dd.uses_int64,
                    "{}_dd uses 64-bit types",
                    decl.name
                );
                assert_eq!(dd.workgroup_size, r.workgroup_size, "{}_dd", decl.name);
            }
            None => assert!(!r.uses_f64, "{} uses f64 and has no _dd variant", decl.name),
        }
    }
}

#[test]
fn every_spirv_file_has_a_declaration() {
    // The library's kernels and the built-in renderer's shaders.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("spirv");
    let mut names: Vec<String> = [dir.clone(), dir.join("render")]
        .iter()
        .flat_map(|d| std::fs::read_dir(d).unwrap())
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "comp").then_some(p)
        })
        .flat_map(|p| {
            let stem = p.file_stem().unwrap().to_str().unwrap().to_owned();
            // build.rs builds a kernel that mentions WLR_VIS twice (WLR-VIS).
            let vis = std::fs::read_to_string(&p).unwrap().contains("WLR_VIS");
            let also = vis.then(|| format!("{stem}_vis"));
            std::iter::once(stem).chain(also)
        })
        .collect();
    names.sort();
    let mut declared: Vec<String> = all().map(|d| d.name.to_owned()).collect();
    declared.sort();
    assert_eq!(names, declared);
}

#[test]
fn a_wrong_declaration_is_caught() {
    let mut decl = *LIBRARY_KERNELS[0];
    // Flip the access of the first binding: must be reported.
    let mut b = decl.bindings.to_vec();
    b[0].access = match b[0].access {
        Access::Read => Access::ReadWrite,
        Access::ReadWrite => Access::Read,
    };
    decl.bindings = Box::leak(b.into_boxed_slice());
    assert!(decl.check(Precision::F32).is_err());
    // A push-constant size that disagrees is reported too.
    let mut decl2 = *LIBRARY_KERNELS[0];
    decl2.push_size += 16;
    assert!(decl2.check(Precision::F32).is_err());
    // Reflection tells f32 from f64 arithmetic.
    let f32_words = spirv(LIBRARY_KERNELS[0].name, Precision::F32).unwrap();
    let f64_words = spirv(LIBRARY_KERNELS[0].name, Precision::F64).unwrap();
    assert!(!reflect("f32", f32_words).unwrap().uses_f64);
    assert!(reflect("f64", f64_words).unwrap().uses_f64);
}
