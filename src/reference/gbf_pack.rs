//! Scalar twin of `spirv/gbf_pack.comp`: the seven filtered feature planes
//! and their variances packed four to a pixel.

/// `[features 0–3, features 4–6 and 0, variances 0–3, variances 4–6 and 0]`,
/// each `4 × pixels` long (pixel-major).
pub fn gbf_pack(feat: [&[f32]; 7], var: [&[f32]; 7]) -> [Vec<f32>; 4] {
    let n = feat[0].len();
    let pack = |p: [&[f32]; 7], first: usize| -> Vec<f32> {
        (0..n)
            .flat_map(|i| (0..4).map(move |k| if first + k < 7 { p[first + k][i] } else { 0.0 }))
            .collect()
    };
    [pack(feat, 0), pack(feat, 4), pack(var, 0), pack(var, 4)]
}

/// Plane `k` (0..7) of a packed pair (`a`: planes 0–3, `b`: 4–6).
pub fn unpack(a: &[f32], b: &[f32], k: usize) -> Vec<f32> {
    let (src, j) = if k < 4 { (a, k) } else { (b, k - 4) };
    src.chunks_exact(4).map(|p| p[j]).collect()
}
