//! Progress bars for long stages (hidden with `--quiet` or when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

pub struct Bar(ProgressBar);

impl Bar {
    /// A bar counting bytes.
    pub fn bytes(stage: &str, quiet: bool) -> Self {
        Self::new(stage, quiet, "{bytes}/{total_bytes} {bytes_per_sec}")
    }

    /// A bar counting items (frames, detections, ...).
    pub fn count(stage: &str, quiet: bool) -> Self {
        Self::new(stage, quiet, "{pos}/{len} {per_sec}")
    }

    fn new(stage: &str, quiet: bool, counter: &str) -> Self {
        let target = if quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        let bar = ProgressBar::with_draw_target(Some(0), target);
        let template = format!("{{prefix:>8}} [{{bar:30}}] {counter} eta {{eta}}");
        bar.set_style(
            ProgressStyle::with_template(&template)
                .expect("valid template")
                .progress_chars("=> "),
        );
        bar.set_prefix(stage.to_string());
        Self(bar)
    }

    pub fn set(&self, done: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }

    /// A line above the bar (printed as is without one).
    pub fn println(&self, line: String) {
        if self.0.is_hidden() {
            println!("{line}");
        } else {
            self.0.println(line);
        }
    }

    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl ingest::Progress for Bar {
    fn bytes(&mut self, done: u64, total: u64) {
        self.set(done, total);
    }
}
