//! What a user checks after `robimu record` and `robimu repair`: the
//! board, the samples, the link's errors and the clock mappings, as text.

use std::fmt;

use robimu_record::repair::{JointClock, RepairReport};
use robimu_record::RecordSummary;

/// The summary of a recording, a line each for the board, the samples,
/// the link, each clock segment and the joint clock.
pub struct RecordSummaryText<'a>(pub &'a RecordSummary);

impl fmt::Display for RecordSummaryText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let p = &s.progress;
        let (v, d) = (s.device.firmware_version, &s.device);
        writeln!(
            f,
            "board: robimu firmware {}.{}.{}, protocol {}, BNO055 chip id {:#04x}, {} Hz",
            v[0], v[1], v[2], d.protocol_version, d.chip_id, d.config.sample_rate_hz
        )?;
        writeln!(
            f,
            "recorded {:.1} s into {}: {} IMU samples ({:.1} Hz), {} joint samples ({:.1} Hz)",
            s.duration,
            s.dir.display(),
            p.imu_samples,
            p.imu_samples as f64 / s.duration.max(1e-9),
            p.joint_samples,
            p.joint_samples as f64 / s.duration.max(1e-9)
        )?;
        writeln!(
            f,
            "link: {} sequence gaps, {} CRC errors, {} other bad frames, {} board restarts; the board dropped {}",
            p.seq_gaps, p.crc_errors, p.bad_frames, p.restarts, p.device_dropped
        )?;
        for (segment, c) in &s.clock {
            writeln!(
                f,
                "clock segment {segment}: device = session + {:.6} s, drift {:+.2} ppm, fit residual {:.1} µs ({} of {} echoes)",
                c.offset,
                c.drift_ppm(),
                c.residual_rms * 1e6,
                c.used,
                c.total
            )?;
        }
        match &s.joint_clock {
            Some(c) => write!(f, "{}", JointClockText(c)),
            None => Ok(()),
        }
    }
}

/// The joint times' controller clock mapping (UR), one line a segment.
pub(crate) struct JointClockText<'a>(pub &'a JointClock);

impl fmt::Display for JointClockText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            JointClock::Mapped(fits) => {
                for (segment, c) in fits {
                    writeln!(
                        f,
                        "joint times from the controller clock, segment {segment}: controller = session + {:.6} s, drift {:+.2} ppm, arrival jitter {:.1} µs RMS ({} samples, {} of {} windows)",
                        c.offset,
                        c.drift_ppm(),
                        c.jitter_rms * 1e6,
                        c.samples,
                        c.windows_used,
                        c.windows
                    )?;
                }
                Ok(())
            }
            JointClock::Kept(why) => writeln!(f, "joint times are host arrival times: {why}"),
        }
    }
}

/// What `robimu repair` did, a line each.
pub struct RepairText<'a>(pub &'a RepairReport);

impl fmt::Display for RepairText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.0;
        for (path, line) in &r.truncated {
            writeln!(f, "{}: removed the cut line {line}", path.display())?;
        }
        for (segment, c) in &r.clock {
            writeln!(
                f,
                "IMU times recomputed, clock segment {segment}: drift {:+.2} ppm, residual {:.1} µs ({} echoes)",
                c.drift_ppm(),
                c.residual_rms * 1e6,
                c.used
            )?;
        }
        if r.unmapped_rows > 0 {
            writeln!(
                f,
                "{} IMU rows belong to a clock segment without ping echoes; their times are as recorded",
                r.unmapped_rows
            )?;
        }
        match &r.joint_clock {
            Some(c) => write!(f, "{}", JointClockText(c)),
            None => Ok(()),
        }
    }
}

/// IMU `j`'s progress line: its board and sensor, samples, rate, gaps and
/// the board's drops.
pub fn imu_progress_line(j: usize, p: &robimu_record::ImuProgress) -> String {
    let file = robimu_session::files::imu_csv(j);
    format!(
        "IMU {j} ({file}, {} sensor {}): {} samples, {:.0}/s, {} gaps, {} dropped by the board",
        p.port, p.sensor, p.samples, p.rate, p.seq_gaps, p.device_dropped
    )
}

/// With several IMUs (docs/model.md §9): a line per IMU and the clock fit
/// of every board after the first (whose fit the summary shows); empty for one.
pub fn imu_lines(summary: &RecordSummary) -> String {
    let p = &summary.progress;
    if p.imus.len() < 2 {
        return String::new();
    }
    let mut out = String::new();
    for (j, imu) in p.imus.iter().enumerate() {
        out += &imu_progress_line(j, imu);
        out.push('\n');
    }
    for board in summary.boards.iter().skip(1) {
        for (segment, c) in &board.clock {
            out += &format!(
                "board {} clock segment {segment}: device = session + {:.6} s, drift {:+.2} ppm, fit residual {:.1} µs\n",
                board.port,
                c.offset,
                c.drift_ppm(),
                c.residual_rms * 1e6
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn a_repair_is_told_a_line_each() {
        let report = RepairReport {
            truncated: vec![(PathBuf::from("s/imu.csv"), 812)],
            clock: Vec::new(),
            unmapped_rows: 3,
            joint_clock: Some(JointClock::Kept("no controller clock".into())),
        };
        assert_eq!(
            RepairText(&report).to_string(),
            "s/imu.csv: removed the cut line 812\n\
             3 IMU rows belong to a clock segment without ping echoes; their times are as recorded\n\
             joint times are host arrival times: no controller clock\n"
        );
        assert_eq!(RepairText(&RepairReport::default()).to_string(), "");
    }
}
