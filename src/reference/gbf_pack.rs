//! Scalar twin of `spirv/gbf_pack.comp`: the seven filtered feature planes
//! and their variances packed four to a pixel.

/// `[features 0–3, features 4–6 and spp, variances 0–3, variances 4–6 and
/// 0]`, each `4 × pixels` long (pixel-major): the sample count rides in the
/// fourth lane of the second (PACKED-SPP).
pub fn gbf_pack(feat: [&[f32]; 7], var: [&[f32]; 7], spp: &[f32]) -> [Vec<f32>; 4] {
    let n = feat[0].len();
    let pack = |p: [&[f32]; 7], first: usize, last: Option<&[f32]>| -> Vec<f32> {
        (0..n)
            .flat_map(|i| {
                (0..4).map(move |k| match (first + k < 7, last) {
                    (true, _) => p[first + k][i],
                    (false, Some(l)) => l[i],
                    (false, None) => 0.0,
                })
            })
            .collect()
    };
    [
        pack(feat, 0, None),
        pack(feat, 4, Some(spp)),
        pack(var, 0, None),
        pack(var, 4, None),
    ]
}

/// Plane `k` (0..7) of a packed pair (`a`: planes 0–3, `b`: 4–6).
pub fn unpack(a: &[f32], b: &[f32], k: usize) -> Vec<f32> {
    let (src, j) = if k < 4 { (a, k) } else { (b, k - 4) };
    src.chunks_exact(4).map(|p| p[j]).collect()
}
