//! What every simulated chip keeps besides its registers: its address and bus state, its
//! clock, the faults injected into it, its counters and its journal, with the accessors a
//! test or a board uses on any of them ([`SimChip`]).

use super::{Faults, JournalEntry, Port};

#[derive(Debug, Clone)]
pub struct ChipCore {
    pub(super) address: u8,
    pub(super) port: Port,
    pub(super) seed: u64,
    /// Run length the noise processes are built for (their flicker band), s.
    pub(super) duration_hint_s: f64,
    runs_started: u64,
    pub(super) samples_made: u64,
    pub(super) time_us: u64,
    pub(super) faults: Faults,
    pub(super) resets: u32,
    journal: Option<Vec<JournalEntry>>,
}

impl ChipCore {
    /// A chip at `address` whose runs are seeded from `seed`, at time 0.
    pub(super) fn new(address: u8, seed: u64) -> Self {
        ChipCore {
            address,
            port: Port::default(),
            seed,
            duration_hint_s: 3600.0,
            runs_started: 0,
            samples_made: 0,
            time_us: 0,
            faults: Faults::default(),
            resets: 0,
            journal: None,
        }
    }

    /// The seed of the next run (a start, a wake-up or a change of settings): every run
    /// draws its own noise, reproducibly.
    pub(super) fn next_run_seed(&mut self) -> u64 {
        self.runs_started += 1;
        self.seed
            .wrapping_add(self.runs_started.wrapping_mul(0x9E37_79B9_7F4A_7C15))
    }

    /// Record `entry` if a journal is kept.
    pub(super) fn note(&mut self, entry: JournalEntry) {
        if let Some(journal) = &mut self.journal {
            journal.push(entry);
        }
    }
}

/// The accessors every simulated chip shares.
pub trait SimChip {
    fn core(&self) -> &ChipCore;
    fn core_mut(&mut self) -> &mut ChipCore;

    /// The same chip at another 7-bit address.
    fn with_address(mut self, address: u8) -> Self
    where
        Self: Sized,
    {
        self.core_mut().address = address;
        self
    }

    /// Build noise processes for runs of about `seconds` (default one hour).
    fn with_duration_hint(mut self, seconds: f64) -> Self
    where
        Self: Sized,
    {
        self.core_mut().duration_hint_s = seconds;
        self
    }

    /// The chip's 7-bit address.
    fn address(&self) -> u8 {
        self.core().address
    }

    fn faults(&self) -> &Faults {
        &self.core().faults
    }

    fn faults_mut(&mut self) -> &mut Faults {
        &mut self.core_mut().faults
    }

    /// A device reset when the clock passes `t_us` (see [`Faults::resets_at_us`]).
    fn schedule_reset(&mut self, t_us: u64) {
        let resets = &mut self.faults_mut().resets_at_us;
        resets.push(t_us);
        resets.sort_unstable();
    }

    /// The chip's clock (the board's time), us.
    fn time_us(&self) -> u64 {
        self.core().time_us
    }

    /// Samples made so far, all runs together, whether or not anyone read them.
    fn samples_made(&self) -> u64 {
        self.core().samples_made
    }

    /// Device resets so far (commanded or injected), after construction.
    fn resets(&self) -> u32 {
        self.core().resets
    }

    /// Start keeping a journal of what the chip does (see [`JournalEntry`]).
    fn keep_journal(&mut self) {
        self.core_mut().journal.get_or_insert_with(Vec::new);
    }

    /// The journal's entries since the last call (empty if no journal is kept).
    fn take_journal(&mut self) -> Vec<JournalEntry> {
        self.core_mut()
            .journal
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }
}
