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
