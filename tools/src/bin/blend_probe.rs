//! Probe for the input blend (INPUT-BLEND, issue #41): every method's rMSE
//! without the stage and with it at each configuration, on the uniform inputs
//! and references `method_mix` leaves in its work folder
//! (`<scene>-<spp>.exr`, `<scene>@<spp>-<w>x<h>-ref.bin`). One JSON line
//! per case and method: the input's rMSE, the method's without the stage
//! (`off`), and with it at each `--config` (keyed by the configuration);
//! raw (the references' own error is the same for every row of a case);
//! `--no-off` leaves the run without the stage out.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin blend_probe -- \
//!     --work /tmp/mm-seed3 --methods wlr,aos \
//!     --config "blend.radius=3 blend.k=1" --config "blend.residual_radius=0"
//! ```

use std::path::PathBuf;

use clap::Parser;
use mcdenoise::{
    colour_of, io, metrics, Config, ContextOptions, Denoiser, GpuContext, InputBlend, Method,
    Options, RgbImage, Source, StatsImage,
};
use mcdenoise_tools::parse_method;

#[derive(Parser)]
struct Args {
    /// `method_mix`'s work folder.
    #[arg(long)]
    work: PathBuf,
    #[arg(long, value_delimiter = ',', default_value = "wlr,lp,apr,aos", value_parser = parse_method)]
    methods: Vec<Method>,
    /// A configuration of the stage to try: `--opt` settings separated by
    /// spaces (`blend.radius`, `blend.k`, `blend.residual_radius`,
    /// `blend.z`); an empty one runs the method's defaults. Repeatable.
    #[arg(long = "config")]
    configs: Vec<String>,
    /// Leave out the run without the stage (`off`).
    #[arg(long)]
    no_off: bool,
    /// Instead: write each method's output without the stage, its error
    /// estimate and the statistics it read (colour, colour variance, spp)
    /// as `<case>-<method>.dump.bin` (13 f32 planes) into this folder, for
    /// trying the stage's parameters offline.
    #[arg(long)]
    dump: Option<PathBuf>,
}

/// `--dump`: one chain run per case and method.
fn dump(
    ctx: &std::sync::Arc<GpuContext>,
    stats: &StatsImage,
    m: Method,
    path: &std::path::Path,
) -> anyhow::Result<()> {
    use mcdenoise::methods::chain::{ChainConfig, ChainInput, GpuChain};
    let config = ChainConfig {
        method: m,
        pass: mcdenoise::Pass::Final,
        precision: mcdenoise::Precision::F32,
        prefilter: mcdenoise::Prefilter::Auto,
        outliers: mcdenoise::Outliers::Auto.resolve(m),
        options: Options::default(),
        low_spp: mcdenoise::has_low_spp(stats),
        debug: false,
        error: true,
        pyramid: false,
        input_blend: false,
        temporal: mcdenoise::Temporal::Off,
        temporal_state: None,
        coarse_map: false,
    };
    let chain = GpuChain::new(ctx, ChainInput::of_image(stats), config)?;
    chain.upload(stats)?;
    let mut batch = mcdenoise::Batch::new(ctx)?;
    chain.record(&mut batch, None, None)?;
    batch.finish()?;
    let out = chain.download()?;
    let clean = chain.clean().download()?;
    let layer = |l: mcdenoise::Layer| {
        clean
            .get(l)
            .ok_or_else(|| anyhow::anyhow!("no {} layer", l.name()))
    };
    let mut bytes = Vec::new();
    let planes = [
        out.color.plane_slices().to_vec(),
        out.error.plane_slices().to_vec(),
        layer(mcdenoise::Layer::Color)?
            .iter()
            .map(|p| &p[..])
            .collect(),
        layer(mcdenoise::Layer::ColorVariance)?
            .iter()
            .map(|p| &p[..])
            .collect(),
        layer(mcdenoise::Layer::Spp)?
            .iter()
            .map(|p| &p[..])
            .collect(),
    ]
    .concat();
    for p in planes {
        bytes.extend_from_slice(bytemuck::cast_slice(p));
    }
    std::fs::write(path, bytes)?;
    Ok(())
}

fn read_ref(path: &std::path::Path, w: usize, h: usize) -> anyhow::Result<RgbImage> {
    let bytes = std::fs::read(path)?;
    let all: &[f32] = bytemuck::cast_slice(&bytes);
    anyhow::ensure!(all.len() == 3 * w * h, "{}: wrong size", path.display());
    let mut r = RgbImage::new(w, h);
    for c in 0..3 {
        r.planes[c].copy_from_slice(&all[c * w * h..(c + 1) * w * h]);
    }
    Ok(r)
}

/// The denoiser of `m` without the stage (`None`) or with it and the
/// options `blend` (space-separated `key=value`), for images like `stats`.
fn denoiser(
    ctx: &std::sync::Arc<GpuContext>,
    stats: &StatsImage,
    m: Method,
    blend: Option<&str>,
) -> anyhow::Result<Denoiser> {
    let mut c = Config::new(m);
    c.error = false;
    c.input_blend = InputBlend::Off;
    if let Some(opts) = blend {
        c.input_blend = InputBlend::On;
        let opts: Vec<String> = opts.split_whitespace().map(str::to_owned).collect();
        c.options = Options::parse(&opts)?;
    }
    Ok(Denoiser::new(ctx, Source::of_image(stats), c)?)
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = std::sync::Arc::new(GpuContext::new(&ContextOptions::default())?);
    let mut cases: Vec<(String, u32, PathBuf)> = Vec::new();
    for e in std::fs::read_dir(&a.work)? {
        let p = e?.path();
        let Some(stem) = p
            .file_name()
            .and_then(|s| s.to_str())
            .and_then(|s| s.strip_suffix(".exr"))
        else {
            continue;
        };
        if let Some((scene, n)) = stem.rsplit_once('-') {
            if let Ok(n) = n.parse() {
                cases.push((scene.to_owned(), n, p.clone()));
            }
        }
    }
    cases.sort();
    let mut denoisers: std::collections::HashMap<(Method, String), Denoiser> = Default::default();
    for (scene, n, path) in cases {
        let stats = io::read_stats(&path)?;
        let (w, h) = (stats.width, stats.height);
        let r = read_ref(&a.work.join(format!("{scene}@{n}-{w}x{h}-ref.bin")), w, h)?;
        let input = metrics::rmse(&colour_of(&stats), &r);
        if let Some(dir) = &a.dump {
            std::fs::create_dir_all(dir)?;
            for &m in &a.methods {
                dump(
                    &ctx,
                    &stats,
                    m,
                    &dir.join(format!("{scene}@{n}-{}.dump.bin", m.name())),
                )?;
            }
            continue;
        }
        for &m in &a.methods {
            let mut line = serde_json::Map::new();
            line.insert("case".into(), format!("{scene}@{n}").into());
            line.insert("method".into(), m.name().into());
            line.insert("input".into(), input.into());
            let off = (!a.no_off).then_some("off");
            for cfg in off.into_iter().chain(a.configs.iter().map(|c| c.as_str())) {
                let blend = (cfg != "off").then_some(cfg);
                let key = (m, cfg.to_owned());
                if !denoisers.contains_key(&key) {
                    denoisers.insert(key.clone(), denoiser(&ctx, &stats, m, blend)?);
                }
                let out = denoisers[&key].denoise(&stats, None)?.color;
                line.insert(cfg.into(), metrics::rmse(&out, &r).into());
            }
            println!("{}", serde_json::Value::Object(line));
        }
    }
    Ok(())
}
