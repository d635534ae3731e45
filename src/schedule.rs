//! The iteration schedule of adaptive sampling (spec §9.3): how many samples
//! each pass of the adaptive loop spends.

use crate::error::{Error, Result};
use crate::methods::Method;

/// Uniform samples per pixel of pass 0 (`s_0`, §9.3).
pub const INITIAL_SPP: u32 = 4;

/// The passes of an adaptive render with an average of `total_spp` samples
/// per pixel over `pixels` pixels: pass 0 gives every pixel `initial_spp`,
/// then each adaptive pass spends `budgets[p]` samples where the previous
/// reconstruction's sample map sends them. The budgets sum to exactly
/// `(total_spp − initial_spp) · pixels`; the last pass takes the remainder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Schedule {
    /// Uniform samples per pixel of pass 0.
    pub initial_spp: u32,
    /// Samples of each adaptive pass (§9.2's `T`).
    pub budgets: Vec<u32>,
}

impl Schedule {
    /// `T_p = floor((N_total − s_0·N_pix)/N_pass)`, the last pass the
    /// remainder (§9.3). Errors: `total_spp < initial_spp`, `passes = 0`
    /// with samples left, or a pass budget above `u32::MAX`.
    pub fn new(total_spp: u32, pixels: usize, initial_spp: u32, passes: u32) -> Result<Schedule> {
        if total_spp < initial_spp {
            return Err(Error::InvalidArgument(format!(
                "an average of {total_spp} spp is below the {initial_spp} uniform samples of pass 0"
            )));
        }
        let rest = (total_spp - initial_spp) as u64 * pixels as u64;
        if rest > 0 && passes == 0 {
            return Err(Error::InvalidArgument(
                "samples are left for adaptive passes but there are none".into(),
            ));
        }
        let each = if passes == 0 { 0 } else { rest / passes as u64 };
        let mut budgets = Vec::with_capacity(passes as usize);
        for p in 0..passes as u64 {
            let t = if p + 1 == passes as u64 {
                rest - each * p
            } else {
                each
            };
            budgets.push(u32::try_from(t).map_err(|_| {
                Error::Limit(format!(
                    "a pass of {t} samples exceeds the sample map's 32-bit budget; use more passes"
                ))
            })?);
        }
        Ok(Schedule {
            initial_spp,
            budgets,
        })
    }

    /// The spec's schedule for `method`: `s_0` = 4 and the method's
    /// `N_pass` ([`crate::MethodInfo::passes`]: 5 for WLR, LP and APR, the
    /// PASSES decision; 3 for AOS; 5 for `none`, whose map follows the input
    /// variance).
    pub fn for_method(method: Method, total_spp: u32, pixels: usize) -> Result<Schedule> {
        Schedule::new(total_spp, pixels, INITIAL_SPP, method.info().passes)
    }

    /// Total samples of the whole render.
    pub fn total(&self, pixels: usize) -> u64 {
        self.initial_spp as u64 * pixels as u64
            + self.budgets.iter().map(|&b| b as u64).sum::<u64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_sum_to_the_average_exactly() {
        for (spp, pixels, passes) in [(16, 256 * 256, 5), (4, 100, 5), (7, 17, 3), (64, 1, 5)] {
            let s = Schedule::new(spp, pixels, 4, passes).unwrap();
            assert_eq!(s.total(pixels), spp as u64 * pixels as u64);
            assert_eq!(s.budgets.len(), passes as usize);
            let first = s.budgets[0];
            assert!(s.budgets[..passes as usize - 1].iter().all(|&b| b == first));
            assert!(*s.budgets.last().unwrap() >= first);
        }
        // 16 spp at 256²: 12·65536 samples in five passes.
        let s = Schedule::for_method(Method::Wlr, 16, 65536).unwrap();
        assert_eq!(s.budgets, vec![157286, 157286, 157286, 157286, 157288]);
        assert_eq!(
            Schedule::for_method(Method::Aos, 16, 10)
                .unwrap()
                .budgets
                .len(),
            3
        );
    }

    #[test]
    fn bad_schedules_are_errors() {
        assert!(Schedule::new(3, 10, 4, 5).is_err());
        assert!(Schedule::new(8, 10, 4, 0).is_err());
        assert_eq!(
            Schedule::new(4, 10, 4, 0).unwrap().budgets,
            Vec::<u32>::new()
        );
        assert!(Schedule::new(u32::MAX, 1 << 20, 4, 1).is_err());
    }
}
