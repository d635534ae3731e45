//! The library reports progress and repairs through `log`; the CLI prints
//! them on stderr (warnings always, the rest unless --quiet or piped).

use std::io::IsTerminal;
use std::sync::OnceLock;

struct StderrLog {
    level: ::log::LevelFilter,
}

impl ::log::Log for StderrLog {
    fn enabled(&self, m: &::log::Metadata) -> bool {
        m.level() <= self.level && m.target().starts_with("mcdenoise")
    }
    fn log(&self, r: &::log::Record) {
        if self.enabled(r.metadata()) {
            match r.level() {
                ::log::Level::Error | ::log::Level::Warn => {
                    eprintln!(
                        "mcdenoise: {}: {}",
                        r.level().as_str().to_lowercase(),
                        r.args()
                    )
                }
                _ => eprintln!("mcdenoise: {}", r.args()),
            }
        }
    }
    fn flush(&self) {}
}

/// Installs the stderr logger: progress lines only on a terminal and without
/// `quiet`, as the progress bars.
pub fn install(quiet: bool) {
    let level = if quiet || !std::io::stderr().is_terminal() {
        ::log::LevelFilter::Warn
    } else {
        ::log::LevelFilter::Info
    };
    static LOGGER: OnceLock<StderrLog> = OnceLock::new();
    if ::log::set_logger(LOGGER.get_or_init(|| StderrLog { level })).is_ok() {
        ::log::set_max_level(level);
    }
}
