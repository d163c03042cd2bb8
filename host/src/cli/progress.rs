//! Progress bars on stderr, drawn only when stderr is a terminal (indicatif hides them
//! otherwise, so pipes and tests see clean output).

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` steps with a message, elapsed time and an estimate of the time left.
pub fn bar(len: u64, message: &'static str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed} (eta {eta})")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message);
    bar
}

/// A spinner for work of unknown length (reading a file), ticking on its own.
pub fn spinner(message: String) -> ProgressBar {
    let spinner = ProgressBar::new_spinner();
    spinner.set_message(message);
    spinner.enable_steady_tick(std::time::Duration::from_millis(120));
    spinner
}
