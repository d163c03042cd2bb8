//! Exact sample accounting from batch indices: every sample the board numbered is either
//! received or counted as lost, never silently bridged.
//!
//! The board numbers samples from 0 at each start ([`protocol::SampleBatch::first_index`]).
//! A batch that starts past the next expected index leaves a gap (lost to a FIFO overflow,
//! a batch dropped for USB back-pressure, or a frame corrupted on the line); one that starts
//! before it repeats indices already seen, which a correct board never does.

use std::ops::Range;

#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SampleAccounting {
    /// Index the next batch should start at.
    next_index: u64,
    received: u64,
    lost: u64,
    /// Each gap as the half-open range of missing indices, in order.
    gaps: Vec<Range<u64>>,
    /// Batches that started before `next_index` (overlap or reordering), ignored.
    out_of_order_batches: u64,
}

impl SampleAccounting {
    pub fn new() -> Self {
        Self::default()
    }

    /// Account for a batch of `len` samples starting at `first_index`. Returns the gap it
    /// revealed, if any, or `Err(())` if the batch overlaps indices already accounted for
    /// (it is then counted and must not be stored).
    #[allow(clippy::result_unit_err)]
    pub fn batch(&mut self, first_index: u64, len: usize) -> Result<Option<Range<u64>>, ()> {
        if first_index < self.next_index {
            self.out_of_order_batches += 1;
            return Err(());
        }
        let gap = (first_index > self.next_index).then_some(self.next_index..first_index);
        if let Some(g) = &gap {
            self.lost += g.end - g.start;
            self.gaps.push(g.clone());
        }
        self.received += len as u64;
        self.next_index = first_index + len as u64;
        Ok(gap)
    }

    /// The board says it produced `total` samples (e.g. at stop): samples after the last
    /// batch received are lost too.
    pub fn close(&mut self, total: u64) -> Option<Range<u64>> {
        if total <= self.next_index {
            return None;
        }
        let gap = self.next_index..total;
        self.lost += total - self.next_index;
        self.gaps.push(gap.clone());
        self.next_index = total;
        Some(gap)
    }

    pub fn received(&self) -> u64 {
        self.received
    }
    pub fn lost(&self) -> u64 {
        self.lost
    }
    /// Samples the board numbered so far: received + lost.
    pub fn expected(&self) -> u64 {
        self.next_index
    }
    pub fn gaps(&self) -> &[Range<u64>] {
        &self.gaps
    }
    pub fn out_of_order_batches(&self) -> u64 {
        self.out_of_order_batches
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_counted_exactly() {
        let mut a = SampleAccounting::new();
        assert_eq!(a.batch(0, 32), Ok(None));
        assert_eq!(a.batch(32, 32), Ok(None));
        assert_eq!(a.batch(96, 10), Ok(Some(64..96)));
        assert_eq!(a.batch(50, 5), Err(()));
        assert_eq!(a.close(110), Some(106..110));
        assert_eq!(a.close(110), None);
        assert_eq!((a.received(), a.lost(), a.expected()), (74, 36, 110));
        assert_eq!(a.received() + a.lost(), a.expected());
        assert_eq!(a.gaps(), &[64..96, 106..110]);
        assert_eq!(a.out_of_order_batches(), 1);
    }
}
