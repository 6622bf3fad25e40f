//! The serial link, host side: [`DeviceMessage`]s out of any
//! [`std::io::Read`] (serial port, pty, recorded file), [`HostMessage`]s into
//! any [`std::io::Write`], and the [`DeviceClock`] that unwraps the device's
//! 32-bit microsecond clock.
//!
//! Framing and decoding are [`robimu_protocol`]'s; this module only adds the
//! `std` plumbing around them.

use std::io::{self, Read, Write};
use std::marker::PhantomData;

use robimu_protocol::{
    encode_to_vec, Decoder, DecoderStats, DeviceMessage, HostMessage, WireError, DELIMITER,
};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Bytes asked of the underlying reader per `read` call.
pub(crate) const READ_CHUNK: usize = 4096;

/// Frame buffer of a [`LinkReader`], in encoded bytes. Larger than the
/// protocol's longest frame so that frames of a newer, larger protocol are
/// reported as [`WireError::WrongVersion`] rather than as over-long.
pub(crate) const LINK_FRAME_CAPACITY: usize = 256;

/// Failure of the serial link itself (protocol faults in single frames are
/// [`WireError`]s, counted in [`DecoderStats`] and not fatal).
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The underlying reader failed (including a serial port's read timeout).
    #[error("reading from the serial link failed")]
    Read(#[source] io::Error),
    /// The underlying writer failed.
    #[error("writing to the serial link failed")]
    Write(#[source] io::Error),
    /// The message could not be framed.
    #[error("could not frame the message")]
    Encode(#[from] WireError),
}

/// Reads frames from `R` and decodes them into messages of type `M`
/// ([`DeviceMessage`] by default).
///
/// Reads in [`READ_CHUNK`]-byte chunks; a frame may be split across reads.
/// `Interrupted` reads are retried; any other read error is returned and the
/// reader stays usable (a partial frame is kept), so a serial port's
/// `TimedOut` can simply be retried.
pub struct LinkReader<R, M = DeviceMessage> {
    inner: R,
    decoder: Decoder<M, LINK_FRAME_CAPACITY>,
    buf: Box<[u8]>,
    /// Unconsumed bytes are `buf[start..end]`.
    start: usize,
    end: usize,
}

impl<R: Read> LinkReader<R> {
    /// A reader of [`DeviceMessage`]s (the host side of the link).
    pub fn new(inner: R) -> Self {
        Self::for_messages(inner)
    }
}

impl<R: Read, M: DeserializeOwned> LinkReader<R, M> {
    /// A reader of any message type, e.g. `LinkReader::<_, HostMessage>`
    /// on the simulated device's side.
    pub fn for_messages(inner: R) -> Self {
        Self {
            inner,
            decoder: Decoder::new(),
            buf: vec![0; READ_CHUNK].into_boxed_slice(),
            start: 0,
            end: 0,
        }
    }

    /// Frames decoded and rejected so far (CRC errors, bytes discarded, …).
    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// The underlying reader.
    pub fn get_ref(&self) -> &R {
        &self.inner
    }

    /// The underlying reader, mutably (e.g. to change a port's timeout).
    pub fn get_mut(&mut self) -> &mut R {
        &mut self.inner
    }

    /// Gives the underlying reader back; buffered bytes are lost.
    pub fn into_inner(self) -> R {
        self.inner
    }

    /// The outcome of the next complete frame: a message, or the
    /// [`WireError`] that rejected it. `Ok(None)` when the reader reports end
    /// of input (`read` returned 0) before a frame completed.
    ///
    /// # Errors
    ///
    /// [`LinkError::Read`] if the underlying reader fails.
    pub fn next_frame(&mut self) -> Result<Option<Result<M, WireError>>, LinkError> {
        loop {
            let pending = self.buf.get(self.start..self.end).unwrap_or_default();
            if !pending.is_empty() {
                let (outcome, rest) = self.decoder.push(pending);
                self.start = self.end - rest.len();
                if outcome.is_some() {
                    return Ok(outcome);
                }
            }
            match self.inner.read(&mut self.buf) {
                Ok(0) => return Ok(None),
                Ok(n) => {
                    self.start = 0;
                    self.end = n.min(self.buf.len());
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(LinkError::Read(e)),
            }
        }
    }

    /// The next message, skipping rejected frames (they are counted in
    /// [`stats`](Self::stats)). `Ok(None)` at end of input.
    ///
    /// # Errors
    ///
    /// [`LinkError::Read`] if the underlying reader fails.
    pub fn next_message(&mut self) -> Result<Option<M>, LinkError> {
        loop {
            match self.next_frame()? {
                None => return Ok(None),
                Some(Ok(msg)) => return Ok(Some(msg)),
                Some(Err(_)) => {}
            }
        }
    }
}

/// Yields [`next_message`](LinkReader::next_message) until end of input.
/// A read error is yielded as `Some(Err(_))`; iterating again retries the read.
impl<R: Read, M: DeserializeOwned> Iterator for LinkReader<R, M> {
    type Item = Result<M, LinkError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_message().transpose()
    }
}

impl<R, M> std::fmt::Debug for LinkReader<R, M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkReader")
            .field("decoder", &self.decoder)
            .field("buffered", &(self.end - self.start))
            .finish_non_exhaustive()
    }
}

/// Frames messages of type `M` ([`HostMessage`] by default) onto `W`.
pub struct LinkWriter<W, M = HostMessage> {
    inner: W,
    _message: PhantomData<fn(&M)>,
}

impl<W: Write> LinkWriter<W> {
    /// A writer of [`HostMessage`]s (the host side of the link).
    pub fn new(inner: W) -> Self {
        Self::for_messages(inner)
    }
}

impl<W: Write, M: Serialize> LinkWriter<W, M> {
    /// A writer of any message type, e.g. `LinkWriter::<_, DeviceMessage>`
    /// on the simulated device's side.
    pub fn for_messages(inner: W) -> Self {
        Self {
            inner,
            _message: PhantomData,
        }
    }

    /// Writes a lone delimiter. Call once after opening the link: it ends
    /// any partial frame the other side still holds, so that the first
    /// message sent is decoded (see [`robimu_protocol::frame`]).
    ///
    /// # Errors
    ///
    /// [`LinkError::Write`] if the underlying writer fails.
    pub fn resync(&mut self) -> Result<(), LinkError> {
        self.write_flushed(&[DELIMITER])
    }

    /// Writes one framed message and flushes.
    ///
    /// # Errors
    ///
    /// [`LinkError::Write`] if the underlying writer fails.
    pub fn send(&mut self, msg: &M) -> Result<(), LinkError> {
        let frame = encode_to_vec(msg)?;
        self.write_flushed(&frame)
    }

    fn write_flushed(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.inner.write_all(bytes).map_err(LinkError::Write)?;
        self.inner.flush().map_err(LinkError::Write)
    }

    /// The underlying writer.
    pub fn get_ref(&self) -> &W {
        &self.inner
    }

    /// The underlying writer, mutably.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.inner
    }

    /// Gives the underlying writer back.
    pub fn into_inner(self) -> W {
        self.inner
    }
}

impl<W, M> std::fmt::Debug for LinkWriter<W, M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkWriter").finish_non_exhaustive()
    }
}

/// Unwraps the device's wrapping 32-bit microsecond clock (`t_us`, modulo
/// 2³², i.e. every 71.6 minutes) into 64-bit microseconds since device boot.
///
/// Each time advances the clock by the *signed* wrapping difference to the
/// previous one, `(t_us − prev) mod 2³²` read as an `i32`: exact while
/// consecutive times are less than 2³¹ µs (35.8 minutes) apart in either
/// direction, so `Sample`, `Status` and `Pong` times — which can interleave
/// slightly out of order — may share one clock. The first time is taken as
/// is (the device clock starts at boot). Call [`reset`](Self::reset) when
/// the device reboots (a fresh `DeviceInfo` arrives).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeviceClock {
    /// Last raw time and its unwrapped value.
    last: Option<(u32, u64)>,
}

impl DeviceClock {
    /// A clock that has seen no time yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Unwraps `t_us` into microseconds since device boot.
    ///
    /// A step back past zero (possible only for corrupt input) saturates at 0.
    pub fn unwrap_us(&mut self, t_us: u32) -> u64 {
        let full = match self.last {
            None => u64::from(t_us),
            Some((raw, full)) => {
                // Reinterpreting the wrapping difference as signed is the point.
                #[allow(clippy::cast_possible_wrap)]
                let step = t_us.wrapping_sub(raw) as i32;
                full.saturating_add_signed(i64::from(step))
            }
        };
        self.last = Some((t_us, full));
        full
    }

    /// Unwraps the time of a message that carries one (`Sample`, `Status`,
    /// `Pong`); `None` for the others.
    pub fn observe(&mut self, msg: &DeviceMessage) -> Option<u64> {
        let t_us = match msg {
            DeviceMessage::Sample(s) => s.t_us,
            DeviceMessage::Status(s) => s.t_us,
            DeviceMessage::Pong(p) => p.t_us,
            DeviceMessage::Info(_) | DeviceMessage::CommandResult(_) => return None,
        };
        Some(self.unwrap_us(t_us))
    }

    /// The last unwrapped time, if any.
    pub fn last_us(&self) -> Option<u64> {
        self.last.map(|(_, full)| full)
    }

    /// Forgets the history (after a device reboot).
    pub fn reset(&mut self) {
        self.last = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_protocol::{encode, ImuSample, Pong, Status, MAX_FRAME_LEN};

    fn frame(msg: &DeviceMessage) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        encode(msg, &mut buf).unwrap().to_vec()
    }

    fn sample(seq: u32) -> DeviceMessage {
        DeviceMessage::Sample(ImuSample {
            sensor: 0,
            seq,
            t_us: seq.wrapping_mul(8_333),
            accel_raw: [1, -2, 981],
            gyro_raw: [0, 4, -4],
            temp_raw: 24,
        })
    }

    /// A reader that hands out the data in small, varying pieces and
    /// interrupts itself now and then, like a serial port.
    struct Trickle {
        data: Vec<u8>,
        pos: usize,
        calls: usize,
        fail_at: Option<usize>,
    }

    impl Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            self.calls += 1;
            if self.calls % 5 == 0 {
                return Err(io::ErrorKind::Interrupted.into());
            }
            if self.fail_at == Some(self.calls) {
                return Err(io::ErrorKind::TimedOut.into());
            }
            let n = (self.calls * 7 % 13 + 1)
                .min(buf.len())
                .min(self.data.len() - self.pos);
            buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
            self.pos += n;
            Ok(n)
        }
    }

    #[test]
    fn reader_decodes_a_trickled_stream_and_counts_crc_errors() {
        let mut data = vec![DELIMITER];
        let mut expected = Vec::new();
        for seq in 0..200 {
            let mut f = frame(&sample(seq));
            if seq % 10 == 3 {
                f[4] ^= 0x40; // a payload byte: a CRC error (or COBS if it became 0)
                assert_ne!(f[4], 0);
            } else {
                expected.push(sample(seq));
            }
            data.extend(f);
        }
        let reader = LinkReader::new(Trickle {
            data,
            pos: 0,
            calls: 0,
            fail_at: None,
        });
        let mut reader = reader;
        let got: Vec<_> = reader.by_ref().map(Result::unwrap).collect();
        assert_eq!(got, expected);
        let s = reader.stats();
        assert_eq!((s.frames_ok, s.crc_errors, s.errors()), (180, 20, 20));
        assert_eq!(s.empty_frames, 1);
    }

    #[test]
    fn read_errors_are_returned_and_reading_resumes() {
        let mut data = Vec::new();
        for seq in 0..20 {
            data.extend(frame(&sample(seq)));
        }
        let mut reader = LinkReader::new(Trickle {
            data,
            pos: 0,
            calls: 0,
            fail_at: Some(12),
        });
        let mut got = Vec::new();
        let mut timeouts = 0;
        loop {
            match reader.next_message() {
                Ok(Some(m)) => got.push(m),
                Ok(None) => break,
                Err(LinkError::Read(e)) if e.kind() == io::ErrorKind::TimedOut => timeouts += 1,
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(timeouts, 1);
        assert_eq!(got, (0..20).map(sample).collect::<Vec<_>>());
    }

    #[test]
    fn next_frame_reports_each_rejected_frame() {
        let mut data = frame(&sample(1));
        data.extend([0x05, 0x01, DELIMITER]); // bad COBS
        data.extend(frame(&sample(2)));
        data.extend(&frame(&sample(3))[..10]); // cut off at end of input
        let mut reader = LinkReader::new(&data[..]);
        assert_eq!(reader.next_frame().unwrap(), Some(Ok(sample(1))));
        assert_eq!(reader.next_frame().unwrap(), Some(Err(WireError::Cobs)));
        assert_eq!(reader.next_frame().unwrap(), Some(Ok(sample(2))));
        assert_eq!(reader.next_frame().unwrap(), None);
        assert_eq!(reader.next_frame().unwrap(), None);
    }

    #[test]
    fn writer_frames_round_trip_through_a_reader() {
        let sent = [
            HostMessage::Start,
            HostMessage::Ping { nonce: 0xDEAD_BEEF },
            HostMessage::Configure(Default::default()),
            HostMessage::GetStatus,
            HostMessage::Stop,
        ];
        let mut writer = LinkWriter::new(Vec::new());
        writer.resync().unwrap();
        for m in &sent {
            writer.send(m).unwrap();
        }
        let bytes = writer.into_inner();
        assert_eq!(bytes[0], DELIMITER);
        // Byte-exact: the writer adds nothing but the frames.
        let mut expected = vec![DELIMITER];
        for m in &sent {
            let mut buf = [0u8; MAX_FRAME_LEN];
            expected.extend(encode(m, &mut buf).unwrap());
        }
        assert_eq!(bytes, expected);
        let mut reader = LinkReader::<_, HostMessage>::for_messages(&bytes[..]);
        let got: Vec<_> = reader.by_ref().map(Result::unwrap).collect();
        assert_eq!(got, sent);
        assert_eq!(reader.stats().errors(), 0);
    }

    #[test]
    fn write_errors_are_typed() {
        struct Broken;
        impl Write for Broken {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                Err(io::ErrorKind::BrokenPipe.into())
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let err = LinkWriter::new(Broken)
            .send(&HostMessage::Start)
            .unwrap_err();
        assert!(matches!(&err, LinkError::Write(e) if e.kind() == io::ErrorKind::BrokenPipe));
    }

    #[test]
    fn clock_unwraps_across_a_wrap() {
        // Start 5 ms before the wrap, 120 Hz-ish steps of 8333 µs.
        let start = u64::from(u32::MAX) - 5_000;
        let mut clock = DeviceClock::new();
        for k in 0..10_000u64 {
            let truth = start + k * 8_333;
            let raw = (truth % (1u64 << 32)) as u32;
            assert_eq!(clock.unwrap_us(raw), truth, "step {k}");
        }
        assert!(clock.last_us().unwrap() > 1u64 << 32);
    }

    #[test]
    fn clock_survives_many_wraps_with_the_largest_steps() {
        let step = (1u64 << 31) - 1;
        let mut clock = DeviceClock::new();
        for k in 0..40u64 {
            let truth = 123 + k * step;
            assert_eq!(clock.unwrap_us((truth % (1u64 << 32)) as u32), truth);
        }
        assert!(clock.last_us().unwrap() > 19 * (1u64 << 32));
    }

    #[test]
    fn clock_accepts_small_steps_back_across_the_wrap() {
        let mut clock = DeviceClock::new();
        let base = u64::from(u32::MAX) - 100;
        let sample_time = base + 300; // after the wrap
        let status_time = base + 50; // before it, arriving later
        let sample = DeviceMessage::Sample(ImuSample {
            sensor: 0,
            seq: 0,
            t_us: (sample_time % (1u64 << 32)) as u32,
            accel_raw: [0; 3],
            gyro_raw: [0; 3],
            temp_raw: 0,
        });
        let status = DeviceMessage::Status(Status {
            t_us: (status_time % (1u64 << 32)) as u32,
            ..Status::default()
        });
        assert_eq!(clock.unwrap_us(base as u32), base);
        assert_eq!(clock.observe(&sample), Some(sample_time));
        assert_eq!(clock.observe(&status), Some(status_time));
        let pong = DeviceMessage::Pong(Pong {
            nonce: 1,
            t_us: ((base + 1_000) % (1u64 << 32)) as u32,
        });
        assert_eq!(clock.observe(&pong), Some(base + 1_000));
        let info_free = DeviceMessage::CommandResult(robimu_protocol::CommandResult {
            command: robimu_protocol::CommandKind::Start,
            result: Ok(()),
        });
        assert_eq!(clock.observe(&info_free), None);
        clock.reset();
        assert_eq!(clock.last_us(), None);
        assert_eq!(clock.unwrap_us(7), 7);
    }
}
