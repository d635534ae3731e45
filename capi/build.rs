//! Generates the C header from `src/lib.rs` with cbindgen into
//! `$OUT_DIR/mcdenoise.h` (`tests/header.rs` checks that the committed
//! `include/mcdenoise.h` equals it), and compiles the C example's
//! accumulation shader (`examples/c/accumulate.comp`, which includes
//! `include/mcdenoise_accum.glsl`) to `$OUT_DIR/accumulate.spv`, and with
//! the position sums to `$OUT_DIR/accumulate_position.spv`, for
//! `tests/c_example.rs`.

use std::path::PathBuf;

use glslang::{
    Compiler, CompilerOptions, ShaderInput, ShaderMessage, ShaderSource, ShaderStage,
    SourceLanguage, SpirvVersion, Target, VulkanVersion,
};

fn main() {
    let crate_dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let root = crate_dir.join("..");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo:rerun-if-changed=src/lib.rs");
    println!("cargo:rerun-if-changed=cbindgen.toml");

    let config =
        cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("capi/cbindgen.toml");
    cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen: the C header")
        .write_to_file(out_dir.join("mcdenoise.h"));

    // The C example's shader: the accumulation header is inlined (glslang's
    // include callback is not wired here; the header has no includes).
    let shader = root.join("examples/c/accumulate.comp");
    let header = root.join("include/mcdenoise_accum.glsl");
    println!("cargo:rerun-if-changed={}", shader.display());
    println!("cargo:rerun-if-changed={}", header.display());
    let text = std::fs::read_to_string(&shader).expect("examples/c/accumulate.comp");
    let inc = std::fs::read_to_string(&header).expect("include/mcdenoise_accum.glsl");
    let text = text.replace("#include \"mcdenoise_accum.glsl\"", &inc);
    let compiler = Compiler::acquire().expect("glslang compiler");
    let options = CompilerOptions {
        source_language: SourceLanguage::GLSL,
        target: Target::Vulkan {
            version: VulkanVersion::Vulkan1_1,
            spirv_version: SpirvVersion::SPIRV1_3,
        },
        version_profile: None,
        messages: ShaderMessage::DEFAULT,
    };
    // Two builds: as written (no position sums), and with them
    // (`accumulate_position.spv`, for the temporal filter's sequence).
    for (name, text) in [
        ("accumulate.spv", text.clone()),
        (
            "accumulate_position.spv",
            text.replacen(
                "#version 450",
                "#version 450\n#define MCDENOISE_ACCUM_POSITION 1",
                1,
            ),
        ),
    ] {
        let source = ShaderSource::from(text);
        let input = ShaderInput::new(
            &source,
            ShaderStage::Compute,
            &options,
            None::<&[(&str, Option<&str>)]>,
            None,
        )
        .unwrap_or_else(|e| panic!("examples/c/accumulate.comp: {e:?}"));
        let words = compiler
            .create_shader(input)
            .and_then(|shader| shader.compile())
            .unwrap_or_else(|e| panic!("examples/c/accumulate.comp: {e}"));
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        std::fs::write(out_dir.join(name), bytes).expect("write the C example's SPIR-V");
    }
}
