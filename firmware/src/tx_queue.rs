//! The fixed transmit queue between frame encoding and the serial port.
//!
//! Whole frames go in or nothing does ([`TxQueue::push`]); bytes leave as the
//! port accepts them. Sample frames may only use the queue up to
//! [`TxQueue::push_with_reserve`]'s reserve, so that replies to the host
//! still fit when the link is backed up.

/// A byte ring buffer of `N` bytes.
#[derive(Debug, Clone)]
pub(crate) struct TxQueue<const N: usize> {
    buf: [u8; N],
    head: usize,
    len: usize,
}

impl<const N: usize> Default for TxQueue<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> TxQueue<N> {
    /// An empty queue.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            head: 0,
            len: 0,
        }
    }

    /// Queued bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Free bytes.
    pub fn free(&self) -> usize {
        N - self.len
    }

    /// Appends all of `bytes`, or nothing if they do not fit; returns whether they did.
    pub fn push(&mut self, bytes: &[u8]) -> bool {
        self.push_with_reserve(bytes, 0)
    }

    /// Appends all of `bytes` only if `reserve` bytes stay free afterwards.
    pub fn push_with_reserve(&mut self, bytes: &[u8], reserve: usize) -> bool {
        if bytes.len().saturating_add(reserve) > self.free() {
            return false;
        }
        for &byte in bytes {
            let at = (self.head + self.len) % N;
            if let Some(slot) = self.buf.get_mut(at) {
                *slot = byte;
            }
            self.len += 1;
        }
        true
    }

    /// The oldest queued bytes that are contiguous in memory (empty if none).
    pub fn front(&self) -> &[u8] {
        let end = (self.head + self.len).min(N);
        self.buf.get(self.head..end).unwrap_or(&[])
    }

    /// Removes the `n` oldest bytes (at most all of them).
    pub fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.len -= n;
        self.head = if self.len == 0 {
            0
        } else {
            (self.head + n) % N
        };
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    fn drain<const N: usize>(q: &mut TxQueue<N>, chunk: usize) -> std::vec::Vec<u8> {
        let mut out = std::vec::Vec::new();
        while !q.is_empty() {
            let front = q.front();
            let n = front.len().min(chunk);
            out.extend_from_slice(&front[..n]);
            q.consume(n);
        }
        out
    }

    #[test]
    fn frames_go_in_whole_and_come_out_in_order_across_the_wrap() {
        let mut q = TxQueue::<10>::new();
        assert!(q.push(&[1, 2, 3, 4, 5, 6]));
        q.consume(4); // head at 4
        assert!(q.push(&[7, 8, 9, 10, 11, 12])); // wraps
        assert!(!q.push(&[13, 14, 15])); // does not fit: nothing written
        assert_eq!(q.len(), 8);
        assert_eq!(q.free(), 2);
        assert_eq!(drain(&mut q, 3), [5, 6, 7, 8, 9, 10, 11, 12]);
    }

    #[test]
    fn reserve_keeps_room_for_replies() {
        let mut q = TxQueue::<10>::new();
        assert!(q.push_with_reserve(&[0; 6], 4));
        assert!(!q.push_with_reserve(&[0; 1], 4));
        assert!(q.push(&[0; 4]));
        assert_eq!(q.free(), 0);
    }
}
