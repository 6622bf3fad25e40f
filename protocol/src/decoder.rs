//! The streaming frame decoder: bytes in arbitrary chunks → messages.
//!
//! [`Decoder`] collects the encoded bytes of one frame in a fixed buffer of
//! `N` bytes until the [`DELIMITER`], then checks it in this order: COBS →
//! length → CRC-32C → version → postcard (exactly one message, no trailing
//! bytes). The CRC is checked before the version so that a corrupted version
//! byte is reported as a CRC error, not as a foreign protocol.
//!
//! It never allocates, never panics and never holds more than `N` bytes:
//! a run of more than `N` bytes without a delimiter is reported once as
//! [`WireError::FrameTooLong`] and skipped up to the next delimiter. Empty
//! frames (two delimiters in a row, see [`crate::frame`]) are skipped without
//! an error. Every outcome is counted in [`DecoderStats`].

use core::marker::PhantomData;

use serde::de::DeserializeOwned;

use crate::frame::crc32c;
use crate::layout::{CRC_LEN, DELIMITER, MIN_DECODED_LEN};
use crate::{
    DeviceMessage, HostMessage, WireError, DEVICE_MAX_FRAME_LEN, HOST_MAX_FRAME_LEN,
    PROTOCOL_VERSION,
};

/// Decoder for device-to-host frames, sized for the longest [`DeviceMessage`].
pub type DeviceDecoder = Decoder<DeviceMessage, DEVICE_MAX_FRAME_LEN>;

/// Decoder for host-to-device frames, sized for the longest [`HostMessage`].
pub type HostDecoder = Decoder<HostMessage, HOST_MAX_FRAME_LEN>;

/// What a [`Decoder`] has seen so far. All counters wrap on overflow.
///
/// Every byte fed is accounted for exactly once:
/// `bytes_received = bytes of valid frames (delimiters included) +
/// empty_frames + bytes_discarded + pending bytes`
/// ([`Decoder::pending_len`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DecoderStats {
    /// Bytes fed to the decoder.
    pub bytes_received: u64,
    /// Bytes of rejected frames (delimiters included) and of over-long runs.
    pub bytes_discarded: u64,
    /// Frames decoded into a message.
    pub frames_ok: u64,
    /// Empty frames (a delimiter right after a delimiter), skipped silently.
    pub empty_frames: u64,
    /// [`WireError::Cobs`] count.
    pub cobs_errors: u64,
    /// [`WireError::Crc`] count.
    pub crc_errors: u64,
    /// [`WireError::WrongVersion`] count.
    pub version_errors: u64,
    /// The version byte of the last frame refused for its version (a
    /// device or host of another protocol version), if any.
    pub foreign_version: Option<u8>,
    /// [`WireError::FrameTooLong`] count.
    pub too_long: u64,
    /// [`WireError::FrameTooShort`] count.
    pub too_short: u64,
    /// [`WireError::Deserialize`] and [`WireError::TrailingBytes`] count.
    pub deserialize_errors: u64,
}

impl DecoderStats {
    /// Total number of rejected frames, all causes.
    pub fn errors(&self) -> u64 {
        self.cobs_errors
            .wrapping_add(self.crc_errors)
            .wrapping_add(self.version_errors)
            .wrapping_add(self.too_long)
            .wrapping_add(self.too_short)
            .wrapping_add(self.deserialize_errors)
    }

    fn count_error(&mut self, e: &WireError) {
        if let WireError::WrongVersion { found } = e {
            self.foreign_version = Some(*found);
        }
        let counter = match e {
            WireError::Cobs => &mut self.cobs_errors,
            WireError::Crc { .. } => &mut self.crc_errors,
            WireError::WrongVersion { .. } => &mut self.version_errors,
            WireError::FrameTooLong { .. } => &mut self.too_long,
            WireError::FrameTooShort { .. } => &mut self.too_short,
            WireError::Deserialize(_) | WireError::TrailingBytes { .. } => {
                &mut self.deserialize_errors
            }
            // Encoding errors never come out of the decoder.
            WireError::Serialize(_) | WireError::BufferTooSmall { .. } => return,
        };
        *counter = counter.wrapping_add(1);
    }
}

/// Streaming decoder of frames carrying messages of type `M`, with a fixed
/// buffer of `N` encoded bytes.
///
/// `N` is the longest frame accepted, delimiter excluded; the aliases
/// [`DeviceDecoder`] and [`HostDecoder`] use the protocol's maxima. A larger
/// `N` lets a receiver report frames of a newer, larger protocol as
/// [`WireError::WrongVersion`] instead of [`WireError::FrameTooLong`].
///
/// ```
/// use robimu_protocol::{encode_device, DeviceDecoder, DeviceMessage, Pong, MAX_FRAME_LEN};
///
/// let msg = DeviceMessage::Pong(Pong { nonce: 7, t_us: 1_000 });
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let frame = encode_device(&msg, &mut buf).unwrap();
///
/// let mut decoder = DeviceDecoder::new();
/// let (first, second) = frame.split_at(3); // any split works
/// assert_eq!(decoder.feed(first).next(), None);
/// assert_eq!(decoder.feed(second).next(), Some(Ok(msg)));
/// assert_eq!(decoder.stats().frames_ok, 1);
/// ```
pub struct Decoder<M, const N: usize> {
    buf: [u8; N],
    /// Encoded bytes of the current frame held in `buf`.
    len: usize,
    /// Skipping an over-long run up to the next delimiter.
    discarding: bool,
    stats: DecoderStats,
    _message: PhantomData<fn() -> M>,
}

impl<M, const N: usize> core::fmt::Debug for Decoder<M, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Decoder")
            .field("capacity", &N)
            .field("pending_len", &self.len)
            .field("discarding", &self.discarding)
            .field("stats", &self.stats)
            .finish()
    }
}

impl<M: DeserializeOwned, const N: usize> Default for Decoder<M, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: DeserializeOwned, const N: usize> Decoder<M, N> {
    /// An empty decoder with zeroed statistics.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            discarding: false,
            stats: DecoderStats {
                bytes_received: 0,
                bytes_discarded: 0,
                frames_ok: 0,
                empty_frames: 0,
                cobs_errors: 0,
                crc_errors: 0,
                version_errors: 0,
                foreign_version: None,
                too_long: 0,
                too_short: 0,
                deserialize_errors: 0,
            },
            _message: PhantomData,
        }
    }

    /// Counters of everything decoded and rejected so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Encoded bytes of an unfinished frame held in the buffer.
    pub fn pending_len(&self) -> usize {
        self.len
    }

    /// Drops any unfinished frame (counted as discarded), e.g. after the link
    /// was reopened. Statistics are kept.
    pub fn reset(&mut self) {
        self.discard(self.len);
        self.len = 0;
        self.discarding = false;
    }

    /// Decodes the frames in `chunk`, in order.
    ///
    /// A frame may be split across any number of chunks; a chunk may hold
    /// any number of frames. Dropping the iterator early still consumes the
    /// rest of `chunk` (its frames are decoded, counted and dropped), so the
    /// decoder stays in step with the byte stream.
    pub fn feed<'d, 'c>(&'d mut self, chunk: &'c [u8]) -> Frames<'d, 'c, M, N> {
        Frames {
            decoder: self,
            rest: chunk,
        }
    }

    /// Consumes `input` up to and including the end of the first frame (or
    /// the first over-long run) and returns its outcome with the unconsumed
    /// rest of `input`; `(None, &[])` once all of `input` is consumed without
    /// completing a frame.
    ///
    /// This is the primitive under [`feed`](Self::feed), for callers that
    /// manage their own input buffer.
    pub fn push<'c>(&mut self, input: &'c [u8]) -> (Option<Result<M, WireError>>, &'c [u8]) {
        let mut rest = input;
        loop {
            let Some(end) = rest.iter().position(|&b| b == DELIMITER) else {
                self.stats.bytes_received = self.stats.bytes_received.wrapping_add(len64(rest));
                return (self.absorb(rest), &[]);
            };
            let (body, tail) = rest.split_at(end);
            let after = tail.get(1..).unwrap_or(&[]);
            self.stats.bytes_received = self.stats.bytes_received.wrapping_add(len64(body) + 1);
            rest = after;

            if self.discarding {
                // The end of an over-long run, already reported.
                self.discarding = false;
                self.discard(body.len() + 1);
                continue;
            }
            if let Some(err) = self.absorb(body) {
                // Over-long, but it ends here: nothing to skip afterwards.
                self.discarding = false;
                self.discard(1);
                return (Some(err), after);
            }
            let frame_len = core::mem::take(&mut self.len);
            if frame_len == 0 {
                self.stats.empty_frames = self.stats.empty_frames.wrapping_add(1);
                continue;
            }
            let result = self.decode_buffered(frame_len);
            match &result {
                Ok(_) => self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1),
                Err(e) => {
                    self.stats.count_error(e);
                    self.discard(frame_len + 1);
                }
            }
            return (Some(result), after);
        }
    }

    /// Appends delimiter-free `bytes` to the current frame, or skips them
    /// while discarding. Returns the error when the frame overflows `N`.
    fn absorb(&mut self, bytes: &[u8]) -> Option<Result<M, WireError>> {
        if self.discarding {
            self.discard(bytes.len());
            return None;
        }
        let start = self.len;
        let end = start.saturating_add(bytes.len());
        match self.buf.get_mut(start..end) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.len = end;
                None
            }
            None => {
                self.discard(end);
                self.len = 0;
                self.discarding = true;
                let err = WireError::FrameTooLong { limit: N };
                self.stats.count_error(&err);
                Some(Err(err))
            }
        }
    }

    fn discard(&mut self, bytes: usize) {
        self.stats.bytes_discarded = self.stats.bytes_discarded.wrapping_add(bytes as u64);
    }

    /// Checks and decodes the `len` encoded bytes at the start of the buffer.
    fn decode_buffered(&mut self, len: usize) -> Result<M, WireError> {
        let encoded = self.buf.get_mut(..len).ok_or(WireError::Cobs)?;
        let decoded_len = cobs::decode_in_place(encoded).map_err(|_| WireError::Cobs)?;
        let decoded = self.buf.get(..decoded_len).ok_or(WireError::Cobs)?;
        decode_frame_body(decoded)
    }
}

/// Checks a COBS-decoded frame (`version ++ payload ++ crc`) and decodes its
/// payload.
fn decode_frame_body<M: DeserializeOwned>(decoded: &[u8]) -> Result<M, WireError> {
    let too_short = WireError::FrameTooShort { len: decoded.len() };
    if decoded.len() < MIN_DECODED_LEN {
        return Err(too_short);
    }
    let (covered, crc_bytes) = decoded
        .split_last_chunk::<CRC_LEN>()
        .ok_or(too_short.clone())?;
    let received = u32::from_le_bytes(*crc_bytes);
    let computed = crc32c(covered);
    if received != computed {
        return Err(WireError::Crc { received, computed });
    }
    let (&version, payload) = covered.split_first().ok_or(too_short)?;
    if version != PROTOCOL_VERSION {
        return Err(WireError::WrongVersion { found: version });
    }
    let (msg, trailing) =
        postcard::take_from_bytes::<M>(payload).map_err(WireError::Deserialize)?;
    if !trailing.is_empty() {
        return Err(WireError::TrailingBytes {
            count: trailing.len(),
        });
    }
    Ok(msg)
}

fn len64(bytes: &[u8]) -> u64 {
    bytes.len() as u64
}

/// Iterator over the outcomes of the frames completed by one chunk; see
/// [`Decoder::feed`].
pub struct Frames<'d, 'c, M: DeserializeOwned, const N: usize> {
    decoder: &'d mut Decoder<M, N>,
    rest: &'c [u8],
}

impl<M: DeserializeOwned, const N: usize> Iterator for Frames<'_, '_, M, N> {
    type Item = Result<M, WireError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        let (outcome, rest) = self.decoder.push(self.rest);
        self.rest = rest;
        outcome
    }
}

impl<M: DeserializeOwned, const N: usize> Drop for Frames<'_, '_, M, N> {
    fn drop(&mut self) {
        for _ in self.by_ref() {}
    }
}
