//! Scalar twin of `spirv/apr_pack.comp` (APR-PACKED): APR's eight feature
//! planes packed four to a pixel.

/// `[normal xyz and albedo r, albedo g b, depth and visibility]`, each
/// `4 × pixels` long (pixel-major); visibility 0 unless `vis`.
pub fn apr_pack(feats: [&[f32]; 8], vis: bool) -> [Vec<f32>; 2] {
    let n = feats[0].len();
    let a = (0..n)
        .flat_map(|i| [feats[0][i], feats[1][i], feats[2][i], feats[3][i]])
        .collect();
    let b = (0..n)
        .flat_map(|i| {
            [
                feats[4][i],
                feats[5][i],
                feats[6][i],
                if vis { feats[7][i] } else { 0.0 },
            ]
        })
        .collect();
    [a, b]
}
