//! Every option the spec names, as `key=value` pairs (`mcdenoise denoise
//! --opt key=value`). One table: parsing, validation and `--help` come from it.

use std::collections::BTreeMap;

use crate::error::{Error, Result};

/// The kind of value an option takes.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Kind {
    /// One of the listed words.
    Choice(&'static [&'static str]),
    /// An integer in `[min, max]`.
    Int(i64, i64),
    /// A real number in `[min, max]`.
    Real(f64, f64),
}

/// One option of the spec.
#[derive(Copy, Clone, Debug)]
pub struct OptionSpec {
    /// The `key` of `--opt key=value`, `<method>.<name>` (e.g. `wlr.reject`).
    pub key: &'static str,
    /// The values it accepts; anything else is an error naming them.
    pub kind: Kind,
    /// Value when the option is not given; `"method"` means the method decides.
    pub default: &'static str,
    /// Section of `docs/algorithms.md`.
    pub section: &'static str,
    /// One line for `--help` ([`help_table`]).
    pub help: &'static str,
}

/// The registry.
pub const OPTIONS: &[OptionSpec] = &[
    OptionSpec {
        key: "wlr.outlier_weight",
        kind: Kind::Choice(&["clamped", "off"]),
        default: "clamped",
        section: "§2.3 step 2",
        help: "weights divided by max(var, 1) (clamped) or not at all (off)",
    },
    OptionSpec {
        key: "wlr.reject",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§2.3 step 3",
        help: "confidence-interval rejection of neighbours on grey",
    },
    OptionSpec {
        key: "wlr.nonneg",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§2.3 step 5",
        help: "positive-weight fallback when a fitted value is negative",
    },
    OptionSpec {
        key: "wlr.extra_features",
        kind: Kind::Choice(&["none", "visibility"]),
        default: "method",
        section: "§2.1 (WLR-VIS, AUTO-VIS)",
        help: "regress on the NL-means filtered visibility as a tenth feature (visibility; needs the layer) or on the spec's nine (none); method: none for WLR, visibility for auto's WLR member in final reconstructions of statistics with the visibility layer (AUTO-VIS)",
    },
    OptionSpec {
        key: "lp.error_mode",
        kind: Kind::Choice(&["varsub", "paper"]),
        default: "varsub",
        section: "§3.4",
        help: "subtract the test pixel's variance from the prediction error (varsub, s=1) or not (paper, s=0)",
    },
    OptionSpec {
        key: "lp.centre_test",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§3.4",
        help: "a window whose model misses its own centre by more than 3 standard errors counts that miss for every pixel of the window (ours; off: the spec)",
    },
    OptionSpec {
        key: "lp.pixel_test",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§3.5",
        help: "a centre whose prediction misses a pixel's own mean by more than 3 standard errors (Student's t for its sample count) does not predict that pixel (ours; off: the spec)",
    },
    OptionSpec {
        key: "lp.outlier_weight",
        kind: Kind::Choice(&["clamped", "off"]),
        default: "clamped",
        section: "§3.3 (LP-OUTLIER-W, LP-OUTLIER-W-ON)",
        help: "pixel i's row in centre c's least squares weighted by 1/max(vbar_i / max(vbar_c, 1), 1), WLR's outlier weight in the centre's noise (clamped: keeps one-sample clusters out of the fits), or unweighted (off, the paper)",
    },
    OptionSpec {
        key: "apr.stages",
        kind: Kind::Int(1, 4),
        default: "2",
        section: "§4.3",
        help: "error-estimation stages T (the reconstruction always filters the input)",
    },
    OptionSpec {
        key: "aos.variance",
        kind: Kind::Choice(&["paper", "sandwich"]),
        default: "paper",
        section: "§5.3 step 5 (AOS-VAR)",
        help: "order-l variance: [A⁻¹BA⁻¹]_00·σ*² as the paper writes it (paper), or Σ l_i² vbar_i, the exact variance of the estimate (sandwich)",
    },
    OptionSpec {
        key: "aos.bias_test",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§5.3 step 5 (AOS-BIAS-TEST)",
        help: "an order's estimated bias counts only when above 2 standard errors of its estimate (on), or always (off, the paper)",
    },
    OptionSpec {
        key: "aos.identity",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§5.3 step 6 (AOS-IDENTITY)",
        help: "the pixel's input competes as a candidate with MSE = its variance (on), or not (off, the paper)",
    },
    OptionSpec {
        key: "aos.identity_floor",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§5.3 step 6 (AOS-IDENTITY-FLOOR)",
        help: "the input candidate's MSE is at least the median per-sample variance of its 3x3 over its own count (on), or its own variance alone (off)",
    },
    OptionSpec {
        key: "aos.outlier_weight",
        kind: Kind::Choice(&["clamped", "off"]),
        default: "clamped",
        section: "§5.3 step 2 (AOS-OUTLIER-W)",
        help: "kernel K divided by max(vbar, 1), as WLR's outlier weight (clamped), or K alone (off, the paper)",
    },
    OptionSpec {
        key: "aos.residual",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§5.3 step 5 (AOS-RESIDUAL)",
        help: "an order's residual at the pixel, when above 3 standard errors, bounds its bias from below (on), or not (off, the paper)",
    },
    OptionSpec {
        key: "aos.feature_noise",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§5.3 step 5 (AOS-FEATNOISE)",
        help: "an order's MSE includes the variance its output inherits from the pixel's own noisy features (on), or not (off, the paper)",
    },
    OptionSpec {
        key: "apr.outlier_weight",
        kind: Kind::Choice(&["clamped", "off"]),
        default: "clamped",
        section: "§4.2 (APR-OUTLIER-W)",
        help: "block kernel K_h divided by max(var, 1) per channel (clamped), as WLR's outlier weight, or K_h alone (off, the paper)",
    },
    OptionSpec {
        key: "apr.pixel_test",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§4.3",
        help: "a block whose prediction misses a pixel's own mean by more than 3 standard errors (Student's t for its sample count) does not predict that pixel (ours, as lp.pixel_test; off: the spec)",
    },
    OptionSpec {
        key: "apr.count_cap",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§4.2 step 1 (APR-COUNT-CAP)",
        help: "the interval test takes a pixel with more than twice the image's mean count at the variance it would have with twice the mean (on; matters on adaptive renders), or at its own (off, the spec)",
    },
    OptionSpec {
        key: "apr.visibility",
        kind: Kind::Choice(&["filtered", "raw"]),
        default: "filtered",
        section: "§4.1 (APR-VIS)",
        help: "the visibility feature: its 3x3 means, NL-means filtered as WLR-VIS and AOS read it (filtered), or the input's (raw, the spec); a block's fit on the raw visibility passes the colour's direct-light noise to the output",
    },
    OptionSpec {
        key: "apr.prefilter",
        kind: Kind::Choice(&["off", "on"]),
        default: "off",
        section: "§4.6",
        help: "APR's own 5x5 polynomial feature prefilter when the G-buffer prefilter does not run; CPU backend only (off: see docs/results-apr.md)",
    },
    OptionSpec {
        key: "auto.aos",
        kind: Kind::Choice(&["on", "off"]),
        default: "off",
        section: "ours (AUTO-AOS)",
        help: "auto blends AOS, on the features from before the G-buffer prefilter, as a fourth member with WLR, LP and APR in final reconstructions (on: 0.93-0.97 of the rMSE for about 6x the GPU time; with --map-method auto its adaptive passes keep three) or not (off)",
    },
    OptionSpec {
        key: "gbf.second_below",
        kind: Kind::Real(0.0, 65536.0),
        default: "8",
        section: "§6.2 step 9 (GBF-SECOND)",
        help: "the G-buffer prefilter filters the features of the pixels with fewer samples than this a second time, with the same weights, over its own output (their variances stay the first pass's): at 4 spp their noise, which the colour's shares, is what the regressions follow; final reconstructions only (0: one pass, the spec)",
    },
    OptionSpec {
        key: "gbf.albedo_nlm",
        kind: Kind::Choice(&["auto", "on", "off"]),
        default: "auto",
        section: "ours (GBF-NLM)",
        help: "after the G-buffer prefilter, the albedo gets AOS's NL-means (§5.2), each channel clamped to 2 standard errors around the prefilter's value: in lens blur and on texture edges the albedo's noise, which the colour shares, is what the regressions follow, and the positions do not tell the prefilter to filter it; final reconstructions only (auto: every method but LP, which loses with it on glossy_cornell; off: the spec)",
    },
    OptionSpec {
        key: "blend.radius",
        kind: Kind::Int(0, 16),
        default: "method",
        section: "ours (INPUT-BLEND)",
        help: "the input blend's variance window: V = max(v, mean of v over (2r+1)^2 pixels without their tenth of largest values, at most 8; BLEND-TRIM) (default: 1 for AOS, 3 for the others)",
    },
    OptionSpec {
        key: "blend.k",
        kind: Kind::Real(0.0, 100.0),
        default: "method",
        section: "ours (INPUT-BLEND)",
        help: "the input blend's weight of the method's error estimate against the input's variance, f' = (V f + W y)/(V + W) with W = max(k E, B), B the residual's bound (default: 2 for AOS, 0.25 for WLR, 0.125 for LP and APR, 1 for auto)",
    },
    OptionSpec {
        key: "blend.residual_radius",
        kind: Kind::Int(0, 16),
        default: "3",
        section: "ours (BLEND-RESIDUAL)",
        help: "the input blend's residual window: the method's error is read as at least the mean of (f - y)^2 - v over (2s+1)^2 pixels, less z of its standard deviation (0: not read)",
    },
    OptionSpec {
        key: "blend.z",
        kind: Kind::Real(0.0, 100.0),
        default: "1",
        section: "ours (BLEND-RESIDUAL)",
        help: "the input blend's residual test: how many of its standard deviations the residual's mean must exceed the variance by",
    },
    OptionSpec {
        key: "outliers.clip",
        kind: Kind::Int(0, 4),
        default: "2",
        section: "§4.4 step 1 (OUTLIER-CLIP)",
        help: "rounds of clipping before detection: each drops from the window statistics the pixels more than 3 sd above the mean of their own window's kept pixels that are also above 3 se (a light) or 50 sd (a far spike), so neither hides a firefly beside it (0: the spec)",
    },
    OptionSpec {
        key: "outliers.rim",
        kind: Kind::Choice(&["on", "off"]),
        default: "on",
        section: "§4.4 step 1 (OUTLIER-RIM)",
        help: "for a pixel whose excess is at most 1.5 of its standard errors (one or two rare paths), a bright 8-neighbour keeps it from detection only if it is a rare path itself (within 3 of its own standard errors) with at least half the pixel's excess, or a steady pixel with less: a light seen directly, or a fainter hit on its edge, does not shield one rare hit on the lamp's rim (off: OUTLIER-ISOLATED, any bright neighbour shields)",
    },
    OptionSpec {
        key: "outliers.wide",
        kind: Kind::Real(0.0, 1.0),
        default: "0.05",
        section: "§4.4 step 4 (OUTLIER-WIDE)",
        help: "an outlier whose grey excess is above this fraction of the grey sum of the reconstruction over its 87x87 window is spread, after the others, over a 431x431 window instead (a rare path whose energy belongs far wider; 0: the spec's single window)",
    },
    OptionSpec {
        key: "temporal.inflate",
        kind: Kind::Real(0.01, 100.0),
        default: "method",
        section: "§10.1 (TEMPORAL-TEST-SCALE)",
        help: "the factor on the method's error estimate in the temporal filter's colour test, where a history whose prediction misses the frame by more than t3 sqrt(factor E (1 + P00)) weighs less (default: the method's output noise over its estimate relative to WLR's where that is far from 1: 0.17 for LP, 1 for the others)",
    },
    OptionSpec {
        key: "sampling.smooth",
        kind: Kind::Real(0.0, 16.0),
        default: "method",
        section: "§9.1",
        help: "σ of the Gaussian on the priority map of the method that makes it (default: 1 for WLR, LP and auto, 4 for APR, 2 for AOS, 0 for none; an adaptive render's maps are WLR's for LP, APR, AOS and auto unless --map-method says otherwise)",
    },
    OptionSpec {
        key: "sampling.floor",
        kind: Kind::Real(0.0, 0.99),
        default: "method",
        section: "§9.2",
        help: "fraction of each sample map's budget spread uniformly before the priority places the rest (ours, SAMPLE-FLOOR)",
    },
];

/// Parsed `--opt` values, validated against [`OPTIONS`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Options {
    values: BTreeMap<&'static str, String>,
}

impl Options {
    /// Parses `key=value` strings. Unknown keys and values of the wrong kind
    /// are errors that list what is accepted.
    pub fn parse<S: AsRef<str>>(pairs: &[S]) -> Result<Options> {
        let mut out = Options::default();
        for pair in pairs {
            let pair = pair.as_ref();
            let (k, v) = pair.split_once('=').ok_or_else(|| {
                Error::InvalidArgument(format!("--opt {pair:?}: expected key=value"))
            })?;
            let spec = OPTIONS.iter().find(|o| o.key == k.trim()).ok_or_else(|| {
                let keys: Vec<_> = OPTIONS.iter().map(|o| o.key).collect();
                Error::InvalidArgument(format!("unknown option {k:?}; known: {}", keys.join(", ")))
            })?;
            let v = v.trim();
            let ok = match spec.kind {
                Kind::Choice(c) => c.contains(&v),
                Kind::Int(lo, hi) => v.parse::<i64>().is_ok_and(|x| (lo..=hi).contains(&x)),
                Kind::Real(lo, hi) => v.parse::<f64>().is_ok_and(|x| x >= lo && x <= hi),
            };
            if !ok {
                return Err(Error::InvalidArgument(format!(
                    "option {}: {v:?} is not {}",
                    spec.key,
                    describe(spec.kind)
                )));
            }
            out.values.insert(spec.key, v.to_owned());
        }
        Ok(out)
    }

    /// The value of `key`: given, else its default (`"method"` means the
    /// method decides).
    pub fn get(&self, key: &str) -> &str {
        self.values.get(key).map(|s| s.as_str()).unwrap_or_else(|| {
            OPTIONS
                .iter()
                .find(|o| o.key == key)
                .unwrap_or_else(|| panic!("option {key} is not in the registry"))
                .default
        })
    }

    /// The value of `key` as a number when it was given explicitly (the
    /// registry has checked its kind); `None` leaves the default to the
    /// caller.
    pub fn number<T: std::str::FromStr>(&self, key: &str) -> Result<Option<T>> {
        if !self.is_set(key) {
            return Ok(None);
        }
        self.value(key).map(Some)
    }

    /// The value of `key` as a number: given, else the registry's default.
    pub fn value<T: std::str::FromStr>(&self, key: &str) -> Result<T> {
        self.get(key)
            .parse()
            .map_err(|_| Error::InvalidArgument(format!("{key}: not a number")))
    }

    /// Sets `key` to `value`, validated as [`Options::parse`] validates it.
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        let one = Options::parse(&[format!("{key}={value}")])?;
        self.values.extend(one.values);
        Ok(())
    }

    /// Whether `key` was given explicitly.
    pub fn is_set(&self, key: &str) -> bool {
        self.values.contains_key(key)
    }

    /// The keys given explicitly.
    pub fn keys(&self) -> impl Iterator<Item = &str> {
        self.values.keys().copied()
    }
}

fn describe(kind: Kind) -> String {
    match kind {
        Kind::Choice(c) => format!("one of {}", c.join("|")),
        Kind::Int(lo, hi) => format!("an integer in [{lo}, {hi}]"),
        Kind::Real(lo, hi) => format!("a number in [{lo}, {hi}]"),
    }
}

/// The option table as text, for `--help`.
pub fn help_table() -> String {
    let mut s = String::from("Options for --opt key=value (spec section, default):\n");
    for o in OPTIONS {
        s.push_str(&format!(
            "  {:<22} {:<24} {} [{}; default {}]\n",
            o.key,
            describe(o.kind),
            o.help,
            o.section,
            o.default
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_validates() {
        let o = Options::parse(&["wlr.reject=off", "sampling.smooth=2"]).unwrap();
        assert_eq!(o.get("wlr.reject"), "off");
        assert_eq!(o.get("sampling.smooth"), "2");
        assert_eq!(o.get("lp.error_mode"), "varsub");
        assert!(Options::parse(&["wlr.reject=maybe"]).is_err());
        assert!(Options::parse(&["sampling.smooth=-1"]).is_err());
        // Options of stages that are not built yet are errors, not ignored.
        assert!(Options::parse(&["aos.order=3"]).is_err());
        assert!(Options::parse(&["apr.stages=9"]).is_err());
        assert!(Options::parse(&["outliers=on"]).is_err());
        assert!(Options::parse(&["nope=1"]).is_err());
        assert!(Options::parse(&["wlr.reject"]).is_err());
    }

    #[test]
    fn help_lists_every_option() {
        let h = help_table();
        for o in OPTIONS {
            assert!(h.contains(o.key));
        }
    }
}
