//! Scalar twin of `spirv/peak_fma.comp`: the same eight FMA chains per
//! invocation in f64 (they converge to the fixed point `c/(1 − m) = 1`).

use crate::shared::PeakPush;

/// Every invocation of the `push.width × push.height` grid (`row0` ignored).
pub fn peak_fma(push: &PeakPush, out: &mut [f32]) {
    let n = push.width as usize * push.height as usize;
    let (m, c) = (0.9990234375f64, 0.0009765625f64);
    for (i, o) in out.iter_mut().enumerate().take(n) {
        let s = (i % 1024) as f64 / 1024.0;
        let a0 = [s, s + 0.125, s + 0.25, s + 0.375];
        let a1 = a0.map(|v| v + 0.5);
        let a2 = a0.map(|v| v * 0.5);
        let a3 = a1.map(|v| v * 0.5);
        let mut acc = [
            a0,
            a1,
            a2,
            a3,
            a0.map(|v| v + 0.0625),
            a1.map(|v| v + 0.0625),
            a2.map(|v| v + 0.0625),
            a3.map(|v| v + 0.0625),
        ];
        for _ in 0..push.iterations {
            for a in acc.iter_mut() {
                for v in a.iter_mut() {
                    *v = v.mul_add(m, c);
                }
            }
        }
        let t: f64 = acc.iter().flatten().sum();
        *o = t as f32;
    }
}
