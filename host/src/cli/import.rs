//! `imunoise import FILE`: a record from elsewhere becomes a session.
//!
//! A third-party file (CSV/text, `.npy`) is copied into the store verbatim with the options
//! needed to read it again (rate, names, scales), not converted: converting SI values back
//! to counts would invent a quantisation, and a copy keeps every digit. It is read anew
//! through `input::load` whenever it is analysed or exported. A capture file (the board's
//! bytes) is stored as a capture session, exactly as if it had been recorded. A ROS bag is
//! stored as its one storage file (a rosbag2 directory's `.mcap` or `.db3`), with the topic
//! read, so that every later reading takes the same topic.

use crate::cli::stored::open_store;
use anyhow::{Context, Result};
use imunoise::capture::{Capture, looks_like_capture};
use imunoise::input::{self, LoadOptions};
use imunoise::store::{Counts, End, ImportSpec, Store};
use std::io::Read;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// A text/CSV table, a NumPy .npy (either gzipped), a capture file, or a ROS bag (ROS 1
    /// .bag, MCAP, a rosbag2 directory or its .db3)
    pub file: PathBuf,
    /// A ROS bag's sensor_msgs/Imu topic (needed when the bag has several)
    #[arg(long)]
    pub topic: Option<String>,
    /// Sample rate in Hz (needed when the file has no time column and no rate in its header;
    /// overrides a time column)
    #[arg(long)]
    pub rate: Option<f64>,
    /// Ignore the file's time column: the rows are uniformly sampled at --rate
    #[arg(long)]
    pub ignore_time: bool,
    /// Session name (default: the date and time of the import)
    #[arg(long)]
    pub name: Option<String>,
    /// A note kept with the session
    #[arg(long)]
    pub note: Option<String>,
    /// Channel names, comma-separated, for inputs without a header
    #[arg(long, value_delimiter = ',')]
    pub names: Vec<String>,
}

pub fn run(args: &ImportArgs, store: Option<&Path>) -> Result<()> {
    let file = &input::rosbag::storage_file(&args.file)?;
    let mut first = Vec::new();
    std::fs::File::open(file)
        .and_then(|f| f.take(1).read_to_end(&mut first))
        .with_context(|| format!("{}", file.display()))?;
    let store = open_store(store)?;
    let id = if looks_like_capture(&first) {
        let bytes = std::fs::read(file).with_context(|| format!("{}", file.display()))?;
        import_capture(&store, args, &bytes)?
    } else {
        let mut spec = ImportSpec {
            rate_hz: args.rate,
            ignore_time: args.ignore_time,
            names: args.names.clone(),
            scales: Vec::new(),
            topic: args.topic.clone(),
        };
        let options = LoadOptions {
            rate_hz: spec.rate_hz,
            ignore_time: spec.ignore_time,
            names: spec.names.clone(),
            topic: spec.topic.clone(),
            ..LoadOptions::default()
        };
        // Read it once now: a file that cannot be read must not become a session.
        let loaded = input::load(file, &options)?;
        crate::cli::stored::print_warnings(&loaded.report.warnings);
        if let Some(bag) = &loaded.report.bag {
            eprintln!("note: {bag}");
            spec.topic = Some(bag.topic.clone());
        }
        let r = &loaded.record;
        store
            .import(
                file,
                &spec,
                args.name.as_deref(),
                args.note.as_deref(),
                r.len() as u64,
                r.rate_hz,
            )?
            .id
    };
    let session = store.find(&id.to_string())?;
    println!(
        "imported {} as session {} '{}': {} samples at {}",
        file.display(),
        session.id,
        session.name,
        session.counts.samples_received,
        crate::cli::sessions::rate_bandwidth(&session)
    );
    Ok(())
}

/// A capture file: its bytes through a session writer, like a recording at infinite speed.
fn import_capture(store: &Store, args: &ImportArgs, bytes: &[u8]) -> Result<i64> {
    let capture = Capture::decode(bytes).with_context(|| format!("{}", args.file.display()))?;
    let mut writer = store.begin_capture(args.name.as_deref(), args.note.as_deref())?;
    writer.write(bytes)?;
    writer.set_board(&capture.info)?;
    let mut decoder = imunoise::capture::StreamDecoder::new(false);
    decoder.feed(bytes);
    let counts = Counts::of(&decoder, bytes.len() as u64);
    Ok(writer.finish(End::Complete, &counts)?)
}
