//! One module per subcommand: its arguments (`Args`) and its `run`.

pub mod bench;
pub mod compare;
pub mod demo;
pub mod denoise;
pub mod info;
pub mod inspect;
pub mod prefilter;
pub mod render;
