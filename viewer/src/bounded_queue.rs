//! A bounded FIFO that drops its oldest entry when full.
//!
//! Owns: the buffer of mesh deltas that arrive while the viewer waits for a snapshot, and the count of what it
//! had to drop. Must not: block, grow past its capacity, or know what it stores.

use std::collections::VecDeque;

/// Bounded first-in first-out queue; pushing onto a full queue drops the oldest entry.
#[derive(Debug, Clone)]
pub struct BoundedQueue<T> {
    items: VecDeque<T>,
    capacity: usize,
    dropped: u64,
}

impl<T> BoundedQueue<T> {
    /// An empty queue holding at most `capacity` entries (at least one).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            items: VecDeque::with_capacity(capacity),
            capacity,
            dropped: 0,
        }
    }

    /// Append `item`, dropping the oldest entry if full. Returns whether one was dropped.
    pub fn push(&mut self, item: T) -> bool {
        let dropped = self.items.len() >= self.capacity;
        if dropped {
            self.items.pop_front();
            self.dropped += 1;
        }
        self.items.push_back(item);
        dropped
    }

    /// Remove and return every entry, oldest first.
    pub fn drain(&mut self) -> impl Iterator<Item = T> + '_ {
        self.items.drain(..)
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Entries dropped since creation.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_queue_drops_oldest() {
        let mut queue = BoundedQueue::new(3);
        for i in 0..5 {
            queue.push(i);
        }
        assert_eq!(queue.len(), 3);
        assert_eq!(queue.dropped(), 2);
        assert_eq!(queue.drain().collect::<Vec<_>>(), vec![2, 3, 4]);
        assert_eq!(queue.len(), 0);
    }

    #[test]
    fn zero_capacity_holds_one() {
        let mut queue = BoundedQueue::new(0);
        assert!(!queue.push('a'));
        assert!(queue.push('b'));
        assert_eq!(queue.drain().collect::<String>(), "b");
    }
}
