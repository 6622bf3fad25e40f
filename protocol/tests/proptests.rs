//! Property tests: round trips of arbitrary messages, robustness against
//! arbitrary bytes, and recovery of intact frames from a stream interleaved
//! with garbage and cut into arbitrary chunks.

mod common;

use common::*;
use proptest::collection::vec;
use proptest::prelude::*;
use robimu_protocol::*;
use serde::de::DeserializeOwned;
use serde::Serialize;

/// What a test stream is made of. Every piece of garbage is followed by a
/// delimiter, as a sender's leading `0x00` after a reconnect guarantees.
#[derive(Debug, Clone)]
enum Piece<M> {
    Intact(M),
    /// Random bytes (zeros included, so they may split into several frames).
    Random(Vec<u8>),
    /// A strict prefix of an encoded frame (delimiter excluded).
    Truncated(M, prop::sample::Index),
    /// An encoded frame with one bit flipped somewhere before its delimiter.
    BitFlipped(M, prop::sample::Index, u8),
    /// A run of non-zero bytes, often longer than any frame.
    Oversize(Vec<u8>),
}

fn random_bytes() -> impl Strategy<Value = Vec<u8>> {
    // Biased towards 0x00 and small values (COBS headers).
    vec(
        prop_oneof![4 => any::<u8>(), 1 => Just(0u8), 2 => 1u8..8],
        0..80,
    )
}

fn pieces<S>(msg: impl Fn() -> S) -> impl Strategy<Value = Vec<Piece<S::Value>>>
where
    S: Strategy + 'static,
    S::Value: Clone + std::fmt::Debug,
{
    let piece = prop_oneof![
        6 => msg().prop_map(Piece::Intact),
        1 => random_bytes().prop_map(Piece::Random),
        1 => (msg(), any::<prop::sample::Index>()).prop_map(|(m, i)| Piece::Truncated(m, i)),
        1 => (msg(), any::<prop::sample::Index>(), 0u8..8)
            .prop_map(|(m, i, b)| Piece::BitFlipped(m, i, b)),
        1 => vec(1u8..=255, 30..250).prop_map(Piece::Oversize),
    ];
    vec(piece, 0..24)
}

/// Builds the byte stream and the list of intact messages in it.
fn build_stream<M: Serialize + Clone>(pieces: &[Piece<M>]) -> (Vec<u8>, Vec<M>) {
    let mut stream = Vec::new();
    let mut intact = Vec::new();
    for p in pieces {
        match p {
            Piece::Intact(m) => {
                stream.extend(frame_of(m));
                intact.push(m.clone());
            }
            Piece::Random(bytes) | Piece::Oversize(bytes) => {
                stream.extend(bytes);
                stream.push(DELIMITER);
            }
            Piece::Truncated(m, at) => {
                let f = frame_of(m);
                let body = &f[..f.len() - 1];
                stream.extend(&body[..at.index(body.len())]);
                stream.push(DELIMITER);
            }
            Piece::BitFlipped(m, at, bit) => {
                let mut f = frame_of(m);
                let n = f.len() - 1;
                f[at.index(n)] ^= 1 << bit;
                stream.extend(&f);
            }
        }
    }
    (stream, intact)
}

/// Feeds `stream` in chunks of the given sizes (cycled) and collects all
/// outcomes; checks the statistics' byte accounting on the way out.
fn decode_chunked<M, const N: usize>(
    dec: &mut Decoder<M, N>,
    stream: &[u8],
    chunk_sizes: &[usize],
) -> Result<Vec<Result<M, WireError>>, TestCaseError>
where
    M: DeserializeOwned + Serialize,
{
    let mut out = Vec::new();
    let mut rest = stream;
    for &size in chunk_sizes.iter().cycle() {
        if rest.is_empty() {
            break;
        }
        let (chunk, tail) = rest.split_at(size.min(rest.len()));
        rest = tail;
        out.extend(dec.feed(chunk));
        prop_assert!(dec.pending_len() <= N);
    }
    let s = *dec.stats();
    let ok_bytes: u64 = out
        .iter()
        .filter_map(|r| r.as_ref().ok())
        .map(|m| frame_of(m).len() as u64)
        .sum();
    prop_assert_eq!(s.bytes_received, stream.len() as u64);
    prop_assert_eq!(
        s.bytes_received,
        ok_bytes + s.empty_frames + s.bytes_discarded + dec.pending_len() as u64
    );
    prop_assert_eq!(s.frames_ok, out.iter().filter(|r| r.is_ok()).count() as u64);
    prop_assert_eq!(s.errors(), out.iter().filter(|r| r.is_err()).count() as u64);
    Ok(out)
}

fn check_interleaved<M, const N: usize>(
    pieces: &[Piece<M>],
    chunk_sizes: &[usize],
) -> Result<(), TestCaseError>
where
    M: DeserializeOwned + Serialize + Clone + PartialEq + std::fmt::Debug,
{
    let (stream, intact) = build_stream(pieces);
    let mut dec = Decoder::<M, N>::new();
    let out = decode_chunked(&mut dec, &stream, chunk_sizes)?;
    let decoded: Vec<M> = out.into_iter().filter_map(Result::ok).collect();
    // Every intact frame, in order, and nothing else: garbage passing
    // CRC-32C + version + postcard has probability ~2^-32 per piece.
    // Messages are compared through their frames (f32 NaNs are not `==`).
    let enc = |ms: &[M]| ms.iter().map(frame_of).collect::<Vec<_>>();
    prop_assert_eq!(enc(&decoded), enc(&intact));
    prop_assert_eq!(dec.pending_len(), 0, "the stream ends with a delimiter");
    Ok(())
}

fn chunk_sizes() -> impl Strategy<Value = Vec<usize>> {
    vec(prop_oneof![1usize..8, 8usize..64, 64usize..600], 1..8)
}

/// Decoded equals original, through `==` when there is no NaN and always
/// bitwise through the re-encoded frame.
fn assert_round_trip<M>(msg: &M, decoded: &M) -> Result<(), TestCaseError>
where
    M: Serialize + PartialEq + std::fmt::Debug,
{
    prop_assert_eq!(frame_of(decoded), frame_of(msg));
    let has_nan = format!("{msg:?}").contains("NaN");
    if !has_nan {
        prop_assert_eq!(decoded, msg);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]

    /// (c) The acceptance test of the issue: 10 000 streams.
    #[test]
    fn intact_frames_survive_garbage_and_any_chunking(
        pieces in pieces(device_message),
        sizes in chunk_sizes(),
    ) {
        check_interleaved::<DeviceMessage, DEVICE_MAX_FRAME_LEN>(&pieces, &sizes)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2_000, ..ProptestConfig::default() })]

    /// (c) for the other direction and for a decoder with spare room.
    #[test]
    fn host_frames_survive_garbage_and_any_chunking(
        pieces in pieces(host_message),
        sizes in chunk_sizes(),
    ) {
        check_interleaved::<HostMessage, HOST_MAX_FRAME_LEN>(&pieces, &sizes)?;
        check_interleaved::<HostMessage, 300>(&pieces, &sizes)?;
    }

    /// (a) Round trip of arbitrary device messages, within the size table.
    #[test]
    fn device_messages_round_trip(msg in device_message()) {
        let frame = frame_of(&msg);
        prop_assert!(frame.len() <= device_variant_max_frame(&msg));
        prop_assert!(frame.len() <= DEVICE_MAX_FRAME_LEN);
        prop_assert!(!frame[..frame.len() - 1].contains(&0));
        prop_assert_eq!(*frame.last().unwrap(), 0);
        let out: Vec<_> = DeviceDecoder::new().feed(&frame).collect();
        prop_assert_eq!(out.len(), 1);
        let decoded = out.into_iter().next().unwrap().unwrap();
        assert_round_trip(&msg, &decoded)?;
    }

    /// (a) Round trip of arbitrary host messages, within the size table.
    #[test]
    fn host_messages_round_trip(msg in host_message()) {
        let frame = frame_of(&msg);
        prop_assert!(frame.len() <= host_variant_max_frame(&msg));
        prop_assert!(frame.len() <= HOST_MAX_FRAME_LEN);
        let out: Vec<_> = HostDecoder::new().feed(&frame).collect();
        prop_assert_eq!(out, vec![Ok(msg)]);
    }

    /// The encoder agrees with the independent reference (CRC + COBS).
    #[test]
    fn encoder_matches_reference(msg in device_message()) {
        let mut buf = [0u8; 64];
        let payload = postcard::to_slice(&msg, &mut buf).unwrap();
        prop_assert_eq!(frame_of(&msg), ref_frame(PROTOCOL_VERSION, payload));
    }

    /// The table-driven CRC agrees with the bitwise definition.
    #[test]
    fn crc_matches_bitwise_reference(data in vec(any::<u8>(), 0..300)) {
        prop_assert_eq!(crc32c(&data), ref_crc32c(&data));
    }

    /// (b) Arbitrary bytes in arbitrary chunks: no panic, bounded buffer,
    /// exact byte accounting, and a valid frame after a delimiter still decodes.
    #[test]
    fn random_streams_never_panic(
        bytes in vec(prop_oneof![4 => any::<u8>(), 1 => Just(0u8), 2 => 1u8..8], 0..3000),
        sizes in chunk_sizes(),
        msg in device_message(),
    ) {
        let mut dec = DeviceDecoder::new();
        decode_chunked(&mut dec, &bytes, &sizes)?;
        let mut tail = vec![DELIMITER];
        tail.extend(frame_of(&msg));
        let out: Vec<_> = dec.feed(&tail).filter_map(Result::ok).collect();
        prop_assert_eq!(out.len(), 1);
        assert_round_trip(&msg, &out[0])?;

        let mut host = HostDecoder::new();
        decode_chunked(&mut host, &bytes, &sizes)?;
    }
}
