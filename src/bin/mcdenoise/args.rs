//! Option values the subcommands share, and their library meanings.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::ValueEnum;

use mcdenoise::{InputBlend, Method, Outliers, Pass, Precision, Prefilter, Pyramid, REGISTRY};

/// `--method`: any method of the registry, by name (its help line from the
/// registry too).
pub fn method_parser() -> impl TypedValueParser<Value = Method> {
    PossibleValuesParser::new(
        REGISTRY
            .iter()
            .map(|i| PossibleValue::new(i.name).help(i.about)),
    )
    .map(|name| Method::from_name(&name).expect("a registered name"))
}

/// `--size WxH`.
pub fn parse_size(s: &str) -> Result<(usize, usize), String> {
    mcdenoise::bench::parse_size(s).map_err(|e| e.to_string())
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    /// Vulkan compute kernels.
    Gpu,
    /// The scalar f64 reference implementation (slow, for checking).
    Cpu,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PassArg {
    /// The final reconstruction (large windows).
    Final,
    /// An adaptive pass's reconstruction (the spec's intermediate windows).
    Intermediate,
}

impl PassArg {
    pub fn get(self) -> Pass {
        match self {
            PassArg::Final => Pass::Final,
            PassArg::Intermediate => Pass::Intermediate,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrecisionArg {
    F32,
    F64,
}

impl PrecisionArg {
    pub fn get(self) -> Precision {
        match self {
            PrecisionArg::F32 => Precision::F32,
            PrecisionArg::F64 => Precision::F64,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrefilterArg {
    /// The G-buffer prefilter when the input has position, position_variance
    /// and position_covariance, for the methods that want it (wlr, lp, apr, auto);
    /// none for aos (its own NL-means prefilter does better there).
    Auto,
    /// G-buffer prefilter with world positions and SURE (spec §6); an error
    /// without the position layers.
    Gbf,
    /// No prefilter.
    None,
}

impl PrefilterArg {
    pub fn get(self) -> Prefilter {
        match self {
            PrefilterArg::Auto => Prefilter::Auto,
            PrefilterArg::Gbf => Prefilter::On,
            PrefilterArg::None => Prefilter::Off,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutliersArg {
    /// On for every reconstruction, off for `--method none`.
    Auto,
    /// Remove bright spikes before the method and put their energy back
    /// around them after it (spec §4.4).
    On,
    /// Keep spikes in the input.
    Off,
}

impl OutliersArg {
    pub fn get(self) -> Outliers {
        match self {
            OutliersArg::Auto => Outliers::Auto,
            OutliersArg::On => Outliers::On,
            OutliersArg::Off => Outliers::Off,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PyramidArg {
    /// On for `--method auto` (on images of at least 16x16), off for the
    /// other methods.
    Auto,
    /// After any reconstruction (not none; images of at least 16x16).
    On,
    /// Never.
    Off,
}

impl PyramidArg {
    pub fn get(self) -> Pyramid {
        match self {
            PyramidArg::Auto => Pyramid::Auto,
            PyramidArg::On => Pyramid::On,
            PyramidArg::Off => Pyramid::Off,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BlendArg {
    /// On after WLR, LP, APR and AOS in a final reconstruction, off
    /// otherwise.
    Auto,
    /// After any reconstruction (not none).
    On,
    /// Never.
    Off,
}

impl BlendArg {
    pub fn get(self) -> InputBlend {
        match self {
            BlendArg::Auto => InputBlend::Auto,
            BlendArg::On => InputBlend::On,
            BlendArg::Off => InputBlend::Off,
        }
    }
}

/// Which samples the rendered features average.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum FeatureSamplesArg {
    /// The colour's own samples.
    Shared,
    /// A camera path and a shadow ray of their own per sample: features
    /// whose noise is not the colour's.
    Independent,
}

impl FeatureSamplesArg {
    /// The renderer's setting.
    pub fn get(self) -> mcdenoise::render::FeatureSamples {
        match self {
            FeatureSamplesArg::Shared => mcdenoise::render::FeatureSamples::Shared,
            FeatureSamplesArg::Independent => mcdenoise::render::FeatureSamples::Independent,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum MapCheckArg {
    /// The final method's default: on for lp and apr.
    Auto,
    /// Whenever another method makes the maps.
    On,
    /// Never: every adaptive pass follows its map.
    Off,
}

impl MapCheckArg {
    /// Whether the render checks its maps, given the final method's
    /// `default`.
    pub fn get(self, default: bool) -> bool {
        match self {
            MapCheckArg::Auto => default,
            MapCheckArg::On => true,
            MapCheckArg::Off => false,
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum TemporalArg {
    /// Every frame alone.
    Off,
    /// The LP temporal filter (spec §10.1) after the method: each pixel's
    /// output is the mean of its frames so far, older ones weighing less,
    /// reprojected by the world position and restarted where its surface
    /// was hidden. Needs the position and depth layers.
    Lp,
    /// APR's temporal window (spec §10.2), offline, with --method apr: each
    /// frame's blocks fit polynomials in space and time over the frames
    /// t-2..t+2 around it.
    Apr,
    /// The LP temporal filter run over the whole sequence forwards and
    /// backwards, the two combined per pixel, offline: every frame sees
    /// the frames before and after it. Frames come out once the sequence
    /// is done; until then a temporary file in TMPDIR holds 72 bytes per
    /// pixel and frame. Needs the position and depth layers.
    LpSmooth,
}

impl TemporalArg {
    pub fn get(self) -> mcdenoise::Temporal {
        match self {
            TemporalArg::Off => mcdenoise::Temporal::Off,
            TemporalArg::Lp => mcdenoise::Temporal::Lp,
            TemporalArg::Apr => mcdenoise::Temporal::Apr,
            TemporalArg::LpSmooth => mcdenoise::Temporal::LpSmooth,
        }
    }

    /// The flag's value as typed (`--temporal NAME`).
    pub fn name(self) -> &'static str {
        match self {
            TemporalArg::Off => "off",
            TemporalArg::Lp => "lp",
            TemporalArg::Apr => "apr",
            TemporalArg::LpSmooth => "lp-smooth",
        }
    }

    /// Whether a filter carries state from frame to frame on the GPU, whose
    /// maps an adaptive pass reads (TEMPORAL-MAP): lp and lp-smooth.
    pub fn filters(self) -> bool {
        matches!(self, TemporalArg::Lp | TemporalArg::LpSmooth)
    }
}
