//! Decoder throughput: 1 000 000 `ImuSample` frames decoded in 4 KiB chunks.
//!
//! `cargo bench -p robimu --bench decode`. Plain `std::time::Instant`: one
//! warm-up pass, then the median of several timed passes. Every pass checks
//! that all frames decoded (count and a checksum over `seq`), so nothing can
//! be optimised away.

use std::hint::black_box;
use std::time::{Duration, Instant};

use robimu_protocol::{encode_device, DeviceDecoder, DeviceMessage, ImuSample, MAX_FRAME_LEN};
use robimu_record::link::LinkReader;

const FRAMES: u32 = 1_000_000;
const CHUNK: usize = 4096;
const REPETITIONS: usize = 7;
/// 921600 baud, 8N1: 10 bits per byte.
const LINK_BYTES_PER_S: f64 = 921_600.0 / 10.0;

/// A moving arm sampled at 1 kHz: readings of a few hundred to a few
/// thousand counts, the clock well past 2²⁸ µs (5-byte varint) and wrapping.
fn stream() -> Vec<u8> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move |span: i32| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 33) as i32).rem_euclid(2 * span + 1) - span
    };
    let mut out = Vec::with_capacity(FRAMES as usize * 30);
    let mut buf = [0u8; MAX_FRAME_LEN];
    for seq in 0..FRAMES {
        let msg = DeviceMessage::Sample(ImuSample {
            sensor: 0,
            seq,
            t_us: 4_000_000_000u32.wrapping_add(seq.wrapping_mul(1_000)),
            accel_raw: [
                next(2_000) as i16,
                next(2_000) as i16,
                981 + next(300) as i16,
            ],
            gyro_raw: [next(1_500) as i16, next(1_500) as i16, next(1_500) as i16],
            temp_raw: 25 + next(2) as i8,
        });
        out.extend_from_slice(encode_device(&msg, &mut buf).expect("fits"));
    }
    out
}

fn expected_checksum() -> u64 {
    (0..u64::from(FRAMES)).sum()
}

fn decode_chunks(bytes: &[u8]) -> (u64, u64) {
    let mut decoder = DeviceDecoder::new();
    let (mut count, mut checksum) = (0u64, 0u64);
    for chunk in bytes.chunks(CHUNK) {
        for outcome in decoder.feed(chunk) {
            if let Ok(DeviceMessage::Sample(s)) = outcome {
                count += 1;
                checksum += u64::from(s.seq);
            }
        }
    }
    (count, checksum)
}

fn decode_link_reader(bytes: &[u8]) -> (u64, u64) {
    let (mut count, mut checksum) = (0u64, 0u64);
    for msg in LinkReader::new(bytes) {
        if let Ok(DeviceMessage::Sample(s)) = msg {
            count += 1;
            checksum += u64::from(s.seq);
        }
    }
    (count, checksum)
}

fn bench(name: &str, bytes: &[u8], run: fn(&[u8]) -> (u64, u64)) {
    let check = |result: (u64, u64)| {
        assert_eq!(
            result,
            (u64::from(FRAMES), expected_checksum()),
            "{name}: frames lost"
        );
    };
    check(run(black_box(bytes))); // warm-up
    let mut times: Vec<Duration> = (0..REPETITIONS)
        .map(|_| {
            let t = Instant::now();
            let result = run(black_box(bytes));
            let elapsed = t.elapsed();
            check(result);
            elapsed
        })
        .collect();
    times.sort();
    let median = times[REPETITIONS / 2].as_secs_f64();
    let frames_per_s = f64::from(FRAMES) / median;
    let mb_per_s = bytes.len() as f64 / median / 1e6;
    println!(
        "{name:<28} median {:>8.2} ms  {:>6.2} Mframes/s  {:>7.1} MB/s  {:>6.1} ns/frame  \
         (min {:.2} ms, max {:.2} ms, {REPETITIONS} runs)",
        median * 1e3,
        frames_per_s / 1e6,
        mb_per_s,
        median * 1e9 / f64::from(FRAMES),
        times[0].as_secs_f64() * 1e3,
        times[REPETITIONS - 1].as_secs_f64() * 1e3,
    );
}

fn main() {
    let bytes = stream();
    let mean_frame = bytes.len() as f64 / f64::from(FRAMES);
    println!(
        "{FRAMES} ImuSample frames, {:.1} MB, {mean_frame:.2} bytes/frame; \
         the 921600-baud link carries {:.0} such frames/s",
        bytes.len() as f64 / 1e6,
        LINK_BYTES_PER_S / mean_frame,
    );
    bench("Decoder::feed, 4 KiB chunks", &bytes, decode_chunks);
    bench("LinkReader over &[u8]", &bytes, decode_link_reader);
}
