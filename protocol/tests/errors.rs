//! One test per `WireError` variant, plus resynchronisation, empty frames,
//! statistics and the `Frames` iterator contract. Bad frames are built with
//! the independent reference encoder in `common`.

mod common;

use common::*;
use robimu_protocol::*;

/// COBS(body ++ crc LE) ++ 0x00 with a caller-chosen CRC.
fn frame_with_crc(body: &[u8], crc: u32) -> Vec<u8> {
    let mut b = body.to_vec();
    b.extend(crc.to_le_bytes());
    let mut f = ref_cobs(&b);
    f.push(0);
    f
}

fn decode_all<M: serde::de::DeserializeOwned, const N: usize>(
    dec: &mut Decoder<M, N>,
    bytes: &[u8],
) -> Vec<Result<M, WireError>> {
    dec.feed(bytes).collect()
}

fn sample() -> DeviceMessage {
    DeviceMessage::Sample(ImuSample {
        sensor: 1,
        seq: 41,
        t_us: 1_000_000,
        accel_raw: [10, -20, 981],
        gyro_raw: [-1, 0, 2],
        temp_raw: 25,
    })
}

#[test]
fn bad_cobs_is_reported_and_the_next_frame_decodes() {
    let mut dec = DeviceDecoder::new();
    // Header 0x05 promises 4 bytes, only 1 follows before the delimiter.
    let mut bytes = vec![0x05, 0x11, 0x00];
    bytes.extend(frame_of(&sample()));
    assert_eq!(
        decode_all(&mut dec, &bytes),
        vec![Err(WireError::Cobs), Ok(sample())]
    );
    let s = dec.stats();
    assert_eq!((s.cobs_errors, s.frames_ok, s.errors()), (1, 1, 1));
    assert_eq!(s.bytes_discarded, 3);
}

#[test]
fn bad_crc_carries_both_values() {
    let body = [PROTOCOL_VERSION, 4]; // HostMessage::GetInfo
    let good = ref_crc32c(&body);
    let mut dec = HostDecoder::new();
    assert_eq!(
        decode_all(&mut dec, &frame_with_crc(&body, good ^ 0x0100)),
        vec![Err(WireError::Crc {
            received: good ^ 0x0100,
            computed: good
        })]
    );
    assert_eq!(
        decode_all(&mut dec, &frame_with_crc(&body, good)),
        vec![Ok(HostMessage::GetInfo)]
    );
    assert_eq!(dec.stats().crc_errors, 1);
}

#[test]
fn single_bit_flips_in_a_frame_never_decode() {
    // CRC-32C detects every single-bit error in the content; flips in COBS
    // headers change the frame structure. Either way: never a message.
    let frame = frame_of(&sample());
    for byte in 0..frame.len() - 1 {
        for bit in 0..8 {
            let mut f = frame.clone();
            f[byte] ^= 1 << bit;
            let mut dec = DeviceDecoder::new();
            let out = decode_all(&mut dec, &f);
            assert!(
                out.iter().all(|r| r.is_err()),
                "byte {byte} bit {bit}: {out:?}"
            );
            assert_eq!(dec.stats().frames_ok, 0);
        }
    }
}

#[test]
fn wrong_version_carries_the_version_seen() {
    let mut dec = HostDecoder::new();
    // 1, 2: the previous versions (their frames are refused, not misread)
    for version in [0u8, 1, 2, 4, 0xFF] {
        assert_eq!(
            decode_all(&mut dec, &ref_frame(version, &[1])),
            vec![Err(WireError::WrongVersion { found: version })]
        );
    }
    assert_eq!(dec.stats().version_errors, 5);
    assert_eq!(dec.stats().foreign_version, Some(0xFF));
}

#[test]
fn corrupted_version_byte_is_a_crc_error_not_a_version_error() {
    let mut f = frame_of(&HostMessage::Stop);
    f[1] ^= 0x01; // version 3 -> 2; the CRC covers it
    let mut dec = HostDecoder::new();
    assert!(matches!(
        decode_all(&mut dec, &f)[..],
        [Err(WireError::Crc { .. })]
    ));
}

#[test]
fn frame_too_long_is_reported_once_and_the_decoder_resynchronises() {
    let mut dec = DeviceDecoder::new();
    let limit = DEVICE_MAX_FRAME_LEN;
    // limit bytes fit; one more overflows. Reported at once, not at the delimiter.
    assert_eq!(decode_all(&mut dec, &vec![0x11; limit]), vec![]);
    assert_eq!(
        decode_all(&mut dec, &[0x11]),
        vec![Err(WireError::FrameTooLong { limit })]
    );
    assert_eq!(dec.pending_len(), 0);
    // The run goes on: nothing more is reported and nothing is buffered.
    for _ in 0..100 {
        assert_eq!(decode_all(&mut dec, &[0x22; 1000]), vec![]);
        assert_eq!(dec.pending_len(), 0);
    }
    // The delimiter ends the run; the next frame decodes.
    let mut bytes = vec![0x00];
    bytes.extend(frame_of(&sample()));
    assert_eq!(decode_all(&mut dec, &bytes), vec![Ok(sample())]);
    let s = *dec.stats();
    assert_eq!((s.too_long, s.errors(), s.frames_ok), (1, 1, 1));
    assert_eq!(s.bytes_discarded, limit as u64 + 1 + 100_000 + 1);
    assert_eq!(
        s.bytes_received,
        s.bytes_discarded + frame_of(&sample()).len() as u64
    );
}

#[test]
fn too_long_frame_ending_in_the_same_chunk() {
    let mut dec = DeviceDecoder::new();
    let mut bytes = vec![0x33; 200];
    bytes.push(0);
    bytes.extend(frame_of(&sample()));
    assert_eq!(
        decode_all(&mut dec, &bytes),
        vec![
            Err(WireError::FrameTooLong {
                limit: DEVICE_MAX_FRAME_LEN
            }),
            Ok(sample())
        ]
    );
    assert_eq!(dec.stats().bytes_discarded, 201);
}

#[test]
fn buffer_size_boundary_is_exact() {
    // status_max: 44 encoded bytes + delimiter.
    let status = DeviceMessage::Status(Status {
        t_us: u32::MAX,
        streaming: true,
        samples_sent: u32::MAX,
        samples_dropped: u32::MAX,
        i2c_errors: u32::MAX,
        sensor_reinits: u32::MAX,
        frames_sent: u32::MAX,
        rx_errors: u32::MAX,
        sensor: u8::MAX,
    });
    let f = frame_of(&status);
    assert_eq!(f.len(), 45);
    let mut fits = Decoder::<DeviceMessage, 44>::new();
    assert_eq!(decode_all(&mut fits, &f), vec![Ok(status)]);
    let mut short = Decoder::<DeviceMessage, 43>::new();
    let mut bytes = f.clone();
    bytes.extend(frame_of(&sample()));
    assert_eq!(
        decode_all(&mut short, &bytes),
        vec![Err(WireError::FrameTooLong { limit: 43 }), Ok(sample())]
    );
}

#[test]
fn frame_too_short() {
    let mut dec = HostDecoder::new();
    // COBS [01] decodes to nothing; 5 bytes is version + CRC without payload.
    let mut bytes = vec![0x01, 0x00];
    bytes.extend(frame_with_crc(
        &[PROTOCOL_VERSION],
        ref_crc32c(&[PROTOCOL_VERSION]),
    ));
    assert_eq!(
        decode_all(&mut dec, &bytes),
        vec![
            Err(WireError::FrameTooShort { len: 0 }),
            Err(WireError::FrameTooShort { len: 5 })
        ]
    );
    assert_eq!(dec.stats().too_short, 2);
}

#[test]
fn deserialize_errors_name_the_postcard_cause() {
    let mut dec = DeviceDecoder::new();
    // Variant 1 (Sample) with its fields missing.
    assert_eq!(
        decode_all(&mut dec, &ref_frame(PROTOCOL_VERSION, &[1, 5])),
        vec![Err(WireError::Deserialize(
            postcard::Error::DeserializeUnexpectedEnd
        ))]
    );
    // Status with `streaming` = 2.
    let mut status = vec![2, 0, 2];
    status.extend([0; 6]);
    assert_eq!(
        decode_all(&mut dec, &ref_frame(PROTOCOL_VERSION, &status)),
        vec![Err(WireError::Deserialize(
            postcard::Error::DeserializeBadBool
        ))]
    );
    // No DeviceMessage variant 9.
    let out = decode_all(&mut dec, &ref_frame(PROTOCOL_VERSION, &[9]));
    assert!(
        matches!(out[..], [Err(WireError::Deserialize(_))]),
        "{out:?}"
    );
    assert_eq!(dec.stats().deserialize_errors, 3);
}

#[test]
fn trailing_bytes_after_a_message_are_rejected() {
    let mut dec = HostDecoder::new();
    assert_eq!(
        decode_all(&mut dec, &ref_frame(PROTOCOL_VERSION, &[1, 0xAA, 0xBB])),
        vec![Err(WireError::TrailingBytes { count: 2 })]
    );
    assert_eq!(dec.stats().deserialize_errors, 1);
}

#[test]
fn buffer_too_small_for_every_shorter_buffer() {
    let msg = sample();
    let len = frame_of(&msg).len();
    for capacity in 0..len {
        let mut buf = vec![0u8; capacity];
        assert_eq!(
            encode_device(&msg, &mut buf),
            Err(WireError::BufferTooSmall { capacity })
        );
    }
    let mut buf = vec![0u8; len];
    assert_eq!(encode_device(&msg, &mut buf).map(<[u8]>::len), Ok(len));
}

#[test]
fn serialize_failure_is_typed() {
    struct Unserialisable;
    impl serde::Serialize for Unserialisable {
        fn serialize<S: serde::Serializer>(&self, _: S) -> Result<S::Ok, S::Error> {
            Err(serde::ser::Error::custom("refuses"))
        }
    }
    let mut buf = [0u8; MAX_FRAME_LEN];
    assert_eq!(
        encode(&Unserialisable, &mut buf),
        Err(WireError::Serialize(postcard::Error::SerdeSerCustom))
    );
}

#[test]
fn empty_frames_are_skipped_silently() {
    let mut dec = DeviceDecoder::new();
    let mut bytes = vec![0, 0, 0];
    bytes.extend(frame_of(&sample()));
    bytes.extend([0, 0]);
    assert_eq!(decode_all(&mut dec, &bytes), vec![Ok(sample())]);
    let s = dec.stats();
    assert_eq!((s.empty_frames, s.errors(), s.bytes_discarded), (5, 0, 0));
}

#[test]
fn leading_delimiter_after_reconnect_recovers_the_first_frame() {
    let frame = frame_of(&sample());
    let mut dec = DeviceDecoder::new();
    // Half a frame from before the reconnect is still buffered.
    assert_eq!(decode_all(&mut dec, &frame[..10]), vec![]);
    // Without a leading delimiter the next frame would be glued to it;
    // with one, the stale half is rejected and the frame decodes.
    let mut bytes = vec![DELIMITER];
    bytes.extend(&frame);
    let out = decode_all(&mut dec, &bytes);
    assert_eq!(out.len(), 2);
    assert!(out[0].is_err());
    assert_eq!(out[1], Ok(sample()));
}

#[test]
fn reset_drops_the_partial_frame() {
    let frame = frame_of(&sample());
    let mut dec = DeviceDecoder::new();
    assert_eq!(decode_all(&mut dec, &frame[..10]), vec![]);
    dec.reset();
    assert_eq!(dec.pending_len(), 0);
    assert_eq!(decode_all(&mut dec, &frame), vec![Ok(sample())]);
    assert_eq!(dec.stats().bytes_discarded, 10);
}

#[test]
fn dropping_the_iterator_early_keeps_the_decoder_in_step() {
    let mut bytes = Vec::new();
    for seq in 0..3 {
        let mut m = sample();
        if let DeviceMessage::Sample(s) = &mut m {
            s.seq = seq;
        }
        bytes.extend(frame_of(&m));
    }
    let split = bytes.len() - 5; // the third frame is cut
    let mut dec = DeviceDecoder::new();
    let first = dec.feed(&bytes[..split]).next();
    assert!(matches!(
        first,
        Some(Ok(DeviceMessage::Sample(ImuSample { seq: 0, .. })))
    ));
    assert_eq!(
        dec.stats().frames_ok,
        2,
        "the dropped iterator consumed frame 1"
    );
    let rest: Vec<_> = dec.feed(&bytes[split..]).collect();
    assert!(matches!(
        rest[..],
        [Ok(DeviceMessage::Sample(ImuSample { seq: 2, .. }))]
    ));
}

#[test]
fn push_returns_the_unconsumed_rest() {
    let a = frame_of(&HostMessage::Start);
    let b = frame_of(&HostMessage::Ping { nonce: 5 });
    let mut bytes = a.clone();
    bytes.extend(&b);
    let mut dec = HostDecoder::new();
    let (first, rest) = dec.push(&bytes);
    assert_eq!(first, Some(Ok(HostMessage::Start)));
    assert_eq!(rest, &b[..]);
    let (second, rest) = dec.push(rest);
    assert_eq!(second, Some(Ok(HostMessage::Ping { nonce: 5 })));
    assert!(rest.is_empty());
    assert_eq!(dec.push(&b[..3]), (None, &[][..]));
}

#[test]
fn display_names_the_cause() {
    let cases = [
        (WireError::Cobs, "COBS"),
        (
            WireError::Crc {
                received: 0x1234_5678,
                computed: 0x9ABC_DEF0,
            },
            "0x12345678",
        ),
        (WireError::WrongVersion { found: 7 }, "version 7"),
        (WireError::FrameTooLong { limit: 44 }, "44"),
        (WireError::FrameTooShort { len: 3 }, "3 decoded bytes"),
        (
            WireError::Deserialize(postcard::Error::DeserializeBadBool),
            "bool",
        ),
        (WireError::TrailingBytes { count: 2 }, "2 bytes"),
        (
            WireError::Serialize(postcard::Error::SerdeSerCustom),
            "serialised",
        ),
        (WireError::BufferTooSmall { capacity: 9 }, "9-byte"),
    ];
    for (e, needle) in cases {
        let text = e.to_string();
        assert!(text.contains(needle), "{text:?} lacks {needle:?}");
        let has_source = std::error::Error::source(&e).is_some();
        assert_eq!(
            has_source,
            matches!(e, WireError::Deserialize(_) | WireError::Serialize(_))
        );
    }
}
