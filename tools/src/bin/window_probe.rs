//! §10.2's temporal window on the twins (`reference::apr_gather`), against
//! APR frame by frame on the same statistics: each animated scene rendered
//! uniformly (`render::sequence`), every frame sanitised, cleaned of
//! outliers and prefiltered by the GPU chain (`denoise_with_statistics`,
//! APR's defaults; the outlier stage's restoration is left out of both),
//! then APR alone and the window on the twins. Prints mean rMSE and
//! temporal error (`metrics::temporal_error`) against per-frame
//! references.
//!
//! ```text
//! cargo run --release -p mcdenoise-tools --bin window_probe -- \
//!     [--scenes pan_room,moving_box,moving_highlight] [--size 64x64] [--spp 16] [--frames 12]
//! ```

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::Parser;
use mcdenoise::reference::apr_block::{Inputs, EPS};
use mcdenoise::reference::apr_gather;
use mcdenoise::reference::spp_total::{spp_total, spp_total_mean};
use mcdenoise::render::adaptive::LoopConfig;
use mcdenoise::render::{reference, sequence, Scene};
use mcdenoise::{
    metrics, Config, ContextOptions, Denoiser, GpuContext, Layer, Method, RgbImage, Source,
    StatsImage, Temporal,
};

#[derive(Parser)]
struct Args {
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "pan_room,moving_box,moving_highlight"
    )]
    scenes: Vec<String>,
    #[arg(long, default_value = "64x64", value_parser = |s: &str| mcdenoise::bench::parse_size(s).map_err(|e| e.to_string()))]
    size: (usize, usize),
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[arg(long, default_value_t = 12)]
    frames: u32,
    #[arg(long, default_value_t = 512)]
    reference: u32,
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// A frame's planes as the twins read them.
struct Planes {
    w: usize,
    h: usize,
    y: Vec<Vec<f32>>,
    v: Vec<Vec<f32>>,
    feats: Vec<Vec<f32>>,
    spp: Vec<f32>,
    nbar: f32,
}

impl Planes {
    fn of(s: &StatsImage) -> Planes {
        let get = |l: Layer| s.get(l).expect("a layer APR reads").to_vec();
        let mut feats = Vec::new();
        for l in [
            Layer::Normal,
            Layer::Albedo,
            Layer::Depth,
            Layer::Visibility,
        ] {
            if let Some(p) = s.get(l) {
                feats.extend(p.iter().cloned());
            }
        }
        let spp = get(Layer::Spp).remove(0);
        Planes {
            w: s.width,
            h: s.height,
            y: get(Layer::Color),
            v: get(Layer::ColorVariance),
            feats,
            nbar: spp_total_mean(spp_total(&spp)),
            spp,
        }
    }

    fn inputs(&self, ch: usize) -> Inputs<'_> {
        Inputs {
            w: self.w,
            h: self.h,
            y: &self.y[ch],
            v: &self.v[ch],
            yprev: &self.y[ch],
            s2prev: &self.v[ch],
            feats: std::array::from_fn(|j| self.feats.get(j).map(|f| f.as_slice())),
            spp: &self.spp,
            clamped: true,
            pixel_test: true,
            nbar: Some(self.nbar),
        }
    }
}

fn image(w: usize, h: usize, planes: &[Vec<f32>]) -> RgbImage {
    RgbImage::from_planes(w, h, std::array::from_fn(|c| planes[c].clone()))
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let ctx = Arc::new(GpuContext::new(&ContextOptions::default())?);
    let stop = AtomicBool::new(false);
    println!("| scene | denoiser | mean rMSE | temporal error |");
    println!("|---|---|---:|---:|");
    for name in &a.scenes {
        let scene = Scene::by_name_or_file(name)?;
        let cfg = LoopConfig::new(Method::None, a.spp, false);
        let (mut stats, mut refs) = (Vec::new(), Vec::new());
        sequence::render_frames(
            &ctx,
            &scene,
            0..a.frames.min(scene.frames()),
            a.size,
            a.seed,
            &cfg,
            Temporal::Off,
            &stop,
            |f| {
                let seed = reference::reference_seed(f.seed);
                let r = reference::reference(
                    &ctx,
                    &f.scene,
                    a.size,
                    a.reference,
                    seed,
                    &stop,
                    |_, _| {},
                )?;
                refs.push(r.image);
                stats.push(f.stats);
                Ok(())
            },
        )?;
        let mut clean = Vec::new();
        for s in &stats {
            let d = Denoiser::new(&ctx, Source::of_image(s), Config::new(Method::Apr))?;
            clean.push(Planes::of(&d.denoise_with_statistics(s, None)?.1));
        }
        let (w, h) = a.size;
        let r: Vec<&RgbImage> = refs.iter().collect();
        let row = |what: &str, out: &[RgbImage]| -> anyhow::Result<()> {
            let o: Vec<&RgbImage> = out.iter().collect();
            let rmse = o
                .iter()
                .zip(&r)
                .map(|(o, r)| metrics::rmse(o, r))
                .sum::<f64>()
                / o.len() as f64;
            let te = metrics::temporal_error(&o, &r)?.unwrap_or(f64::NAN);
            println!("| {name} | {what} | {rmse:.5} | {te:.6} |");
            Ok(())
        };
        let alone: Vec<RgbImage> = clean
            .iter()
            .map(|p| {
                let inp: [Inputs; 3] = std::array::from_fn(|ch| p.inputs(ch));
                image(w, h, &apr_gather::run(&inp, 2, EPS).0)
            })
            .collect();
        row("apr", &alone)?;
        let inputs: Vec<[Inputs; 3]> = clean
            .iter()
            .map(|p| std::array::from_fn(|ch| p.inputs(ch)))
            .collect();
        let window: Vec<RgbImage> = apr_gather::run_sequence(&inputs, 2, EPS)
            .iter()
            .map(|o| image(w, h, o))
            .collect();
        row("apr + 10.2", &window)?;
    }
    Ok(())
}
