//! A decoder of the two ROS 2 messages robimu imports, serialised as CDR.
//!
//! ROS 2 (the `ros2msg` schema encoding, message encoding `cdr`) writes a
//! message as OMG CDR: a 4-byte encapsulation header, then the fields in
//! declaration order.
//!
//! ```text
//! header   [0, id]  [options, options]      id: 0 CDR_BE, 1 CDR_LE,
//!                                           6 CDR2_BE, 7 CDR2_LE (plain, final types)
//! uint32   aligned to 4 (relative to the end of the header)
//! float64  aligned to 8 (CDR), to 4 (CDR2)
//! string   uint32 length including the NUL, the bytes, NUL
//! T[]      uint32 count, the elements (each aligned)
//! T[N]     N elements, no count
//! ```
//!
//! Layouts (sensor_msgs, std_msgs, builtin_interfaces, geometry_msgs):
//!
//! ```text
//! Header     { Time stamp { int32 sec; uint32 nanosec }; string frame_id }
//! PoseStamped      { Header header; Pose pose { Point position (x, y, z);
//!                    Quaternion orientation (x, y, z, w) } }
//! TransformStamped { Header header; string child_frame_id;
//!                    Transform transform { Vector3 translation;
//!                    Quaternion rotation (x, y, z, w) } }
//! TFMessage        { TransformStamped[] transforms }   (tf2_msgs, /tf)
//! JointState { Header header; string[] name;
//!              float64[] position; float64[] velocity; float64[] effort }
//! Imu        { Header header; Quaternion orientation (x, y, z, w);
//!              float64[9] orientation_covariance;
//!              Vector3 angular_velocity (rad/s); float64[9] …_covariance;
//!              Vector3 linear_acceleration (m/s²); float64[9] …_covariance }
//! ```

/// Why a message could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer bytes than the message needs.
    #[error("message truncated: needs {needed} bytes at offset {offset}, has {len}")]
    Truncated {
        /// Where the read started (from the start of the message).
        offset: usize,
        /// Bytes it needed.
        needed: usize,
        /// Length of the message.
        len: usize,
    },
    /// An encapsulation this decoder does not read (parameter lists, XCDR2
    /// with headers, …).
    #[error(
        "unsupported CDR encapsulation 0x{0:04x} (reads CDR and plain CDR2, either byte order)"
    )]
    Encapsulation(u16),
    /// A string that is not NUL-terminated UTF-8.
    #[error("bad string at offset {offset}: {detail}")]
    BadString {
        /// Where the string's length field is.
        offset: usize,
        /// What is wrong.
        detail: &'static str,
    },
    /// A sequence longer than the bytes left could hold.
    #[error("sequence of {count} elements at offset {offset} is longer than the message")]
    BadLength {
        /// Where the count is.
        offset: usize,
        /// The count read.
        count: u32,
    },
    /// A `header.stamp.nanosec` of a second or more (ROS 2 keeps it below
    /// 10⁹).
    #[error("header.stamp.nanosec is {0}, not below 10^9 (a corrupted stamp)")]
    BadStamp(u32),
}

/// `builtin_interfaces/Time` in nanoseconds since the epoch of its clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Stamp(pub i64);

/// `sensor_msgs/msg/JointState` (header and positions; velocity and effort
/// are read past).
#[derive(Debug, Clone, PartialEq)]
pub struct JointStateMsg {
    /// `header.stamp`.
    pub stamp: Stamp,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Joint names (may be empty: positions are then in the robot's order).
    pub name: Vec<String>,
    /// Joint positions, rad (m for prismatic joints).
    pub position: Vec<f64>,
}

/// `sensor_msgs/msg/Imu` (header, angular velocity, linear acceleration).
#[derive(Debug, Clone, PartialEq)]
pub struct ImuMsg {
    /// `header.stamp`.
    pub stamp: Stamp,
    /// `header.frame_id`.
    pub frame_id: String,
    /// `angular_velocity`, rad/s.
    pub angular_velocity: [f64; 3],
    /// `linear_acceleration`, m/s².
    pub linear_acceleration: [f64; 3],
}

/// A pose from `geometry_msgs/msg/PoseStamped` or one transform of a
/// `tf2_msgs/msg/TFMessage` (`geometry_msgs/msg/TransformStamped`): the pose
/// of frame `child_frame_id` (a PoseStamped's: empty) in `frame_id`, the
/// quaternion reordered w first as sessions store it (docs MODEL.md §10).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseMsg {
    /// `header.stamp`.
    pub stamp: Stamp,
    /// `header.frame_id`: the frame the pose is given in.
    pub frame_id: String,
    /// A transform's `child_frame_id` (empty for a PoseStamped).
    pub child_frame_id: String,
    /// Position or translation, m.
    pub position: [f64; 3],
    /// Orientation or rotation, (w, x, y, z) (ROS sends x, y, z, w).
    pub orientation: [f64; 4],
}

impl PoseMsg {
    /// Decodes one CDR-serialised `geometry_msgs/msg/PoseStamped`.
    pub fn decode_pose_stamped(data: &[u8]) -> Result<Self, CdrError> {
        let mut r = Reader::new(data)?;
        let (stamp, frame_id) = r.header()?;
        let (position, orientation) = r.pose()?;
        Ok(Self {
            stamp,
            frame_id,
            child_frame_id: String::new(),
            position,
            orientation,
        })
    }

    /// Decodes one CDR-serialised `tf2_msgs/msg/TFMessage`: its transforms
    /// in order.
    pub fn decode_tf(data: &[u8]) -> Result<Vec<Self>, CdrError> {
        let mut r = Reader::new(data)?;
        // a TransformStamped is at least 8 (stamp) + 4 + 4 (two strings) + 56
        let n = r.count(72)?;
        (0..n).map(|_| Self::transform(&mut r)).collect()
    }

    /// Decodes one CDR-serialised `geometry_msgs/msg/TransformStamped` (a
    /// topic of single transforms, not `/tf`'s list).
    pub fn decode_transform_stamped(data: &[u8]) -> Result<Self, CdrError> {
        Self::transform(&mut Reader::new(data)?)
    }

    /// A `TransformStamped` at the reader's position.
    fn transform(r: &mut Reader<'_>) -> Result<Self, CdrError> {
        let (stamp, frame_id) = r.header()?;
        let child_frame_id = r.string()?;
        let (position, orientation) = r.pose()?;
        Ok(Self {
            stamp,
            frame_id,
            child_frame_id,
            position,
            orientation,
        })
    }
}

/// A cursor over one CDR message.
struct Reader<'a> {
    data: &'a [u8],
    /// Position in `data` (which includes the 4-byte header).
    pos: usize,
    little: bool,
    /// Largest alignment: 8 in CDR, 4 in CDR2.
    max_align: usize,
}

const HEADER: usize = 4;

impl<'a> Reader<'a> {
    fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        if data.len() < HEADER {
            return Err(CdrError::Truncated {
                offset: 0,
                needed: HEADER,
                len: data.len(),
            });
        }
        let id = u16::from_be_bytes([data[0], data[1]]);
        let (little, max_align) = match id {
            0x0000 => (false, 8),
            0x0001 => (true, 8),
            0x0006 => (false, 4),
            0x0007 => (true, 4),
            other => return Err(CdrError::Encapsulation(other)),
        };
        Ok(Self {
            data,
            pos: HEADER,
            little,
            max_align,
        })
    }

    /// Skips padding so that the next `size`-byte value is aligned relative
    /// to the end of the encapsulation header.
    fn align(&mut self, size: usize) {
        let a = size.min(self.max_align);
        let rel = self.pos - HEADER;
        self.pos += (a - rel % a) % a;
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], CdrError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        match end {
            Some(end) => {
                let s = &self.data[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(CdrError::Truncated {
                offset: self.pos,
                needed: n,
                len: self.data.len(),
            }),
        }
    }

    fn u32(&mut self) -> Result<u32, CdrError> {
        self.align(4);
        let b: [u8; 4] = self.take(4)?.try_into().expect("4 bytes");
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn i32(&mut self) -> Result<i32, CdrError> {
        Ok(self.u32()? as i32)
    }

    fn f64(&mut self) -> Result<f64, CdrError> {
        self.align(8);
        let b: [u8; 8] = self.take(8)?.try_into().expect("8 bytes");
        Ok(if self.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }

    fn f64s<const N: usize>(&mut self) -> Result<[f64; N], CdrError> {
        let mut v = [0.0; N];
        for x in &mut v {
            *x = self.f64()?;
        }
        Ok(v)
    }

    /// A sequence count, checked against the bytes left (each element takes
    /// at least `min_size` bytes).
    fn count(&mut self, min_size: usize) -> Result<usize, CdrError> {
        self.align(4);
        let offset = self.pos;
        let count = self.u32()?;
        let left = self.data.len() - self.pos;
        if (count as usize).saturating_mul(min_size) > left {
            return Err(CdrError::BadLength { offset, count });
        }
        Ok(count as usize)
    }

    fn string(&mut self) -> Result<String, CdrError> {
        self.align(4);
        let offset = self.pos;
        let len = self.u32()? as usize;
        if len == 0 {
            // Some encoders write an empty string as length 0, no NUL.
            return Ok(String::new());
        }
        let bytes = self.take(len)?;
        let (text, nul) = bytes.split_at(len - 1);
        if nul != [0] {
            return Err(CdrError::BadString {
                offset,
                detail: "not NUL-terminated",
            });
        }
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::BadString {
            offset,
            detail: "not UTF-8",
        })
    }

    fn f64_seq(&mut self) -> Result<Vec<f64>, CdrError> {
        let n = self.count(8)?;
        (0..n).map(|_| self.f64()).collect()
    }

    /// `std_msgs/Header`: the stamp in ns and the frame id.
    /// A Point/Vector3 then a Quaternion (x, y, z, w), the quaternion
    /// returned w first.
    fn pose(&mut self) -> Result<([f64; 3], [f64; 4]), CdrError> {
        let position: [f64; 3] = self.f64s()?;
        let [x, y, z, w]: [f64; 4] = self.f64s()?;
        Ok((position, [w, x, y, z]))
    }

    fn header(&mut self) -> Result<(Stamp, String), CdrError> {
        let sec = self.i32()?;
        let nanosec = self.u32()?;
        if nanosec >= 1_000_000_000 {
            return Err(CdrError::BadStamp(nanosec));
        }
        let frame_id = self.string()?;
        Ok((Stamp(sec as i64 * 1_000_000_000 + nanosec as i64), frame_id))
    }
}

impl JointStateMsg {
    /// Decodes one CDR-serialised `sensor_msgs/msg/JointState`.
    pub fn decode(data: &[u8]) -> Result<Self, CdrError> {
        let mut r = Reader::new(data)?;
        let (stamp, frame_id) = r.header()?;
        let n = r.count(4)?;
        let name = (0..n).map(|_| r.string()).collect::<Result<_, _>>()?;
        let position = r.f64_seq()?;
        let _velocity = r.f64_seq()?;
        let _effort = r.f64_seq()?;
        Ok(Self {
            stamp,
            frame_id,
            name,
            position,
        })
    }
}

impl ImuMsg {
    /// Decodes one CDR-serialised `sensor_msgs/msg/Imu`.
    pub fn decode(data: &[u8]) -> Result<Self, CdrError> {
        let mut r = Reader::new(data)?;
        let (stamp, frame_id) = r.header()?;
        let _orientation: [f64; 4] = r.f64s()?;
        let _orientation_covariance: [f64; 9] = r.f64s()?;
        let angular_velocity = r.f64s()?;
        let _angular_velocity_covariance: [f64; 9] = r.f64s()?;
        let linear_acceleration = r.f64s()?;
        let _linear_acceleration_covariance: [f64; 9] = r.f64s()?;
        Ok(Self {
            stamp,
            frame_id,
            angular_velocity,
            linear_acceleration,
        })
    }
}

/// A CDR encoder of the same two messages, the inverse of the decoders:
/// for writing ROS 2 recordings (tests, examples). Little-endian CDR.
pub mod encode {
    use super::{ImuMsg, JointStateMsg, PoseMsg, HEADER};

    struct Writer {
        out: Vec<u8>,
    }

    impl Writer {
        fn new() -> Self {
            Self {
                out: vec![0x00, 0x01, 0x00, 0x00],
            }
        }
        fn align(&mut self, a: usize) {
            while (self.out.len() - HEADER) % a != 0 {
                self.out.push(0);
            }
        }
        fn u32(&mut self, v: u32) {
            self.align(4);
            self.out.extend_from_slice(&v.to_le_bytes());
        }
        fn f64(&mut self, v: f64) {
            self.align(8);
            self.out.extend_from_slice(&v.to_le_bytes());
        }
        fn string(&mut self, s: &str) {
            self.u32(s.len() as u32 + 1);
            self.out.extend_from_slice(s.as_bytes());
            self.out.push(0);
        }
        fn f64_seq(&mut self, v: &[f64]) {
            self.u32(v.len() as u32);
            for &x in v {
                self.f64(x);
            }
        }
        fn header(&mut self, stamp_ns: i64, frame_id: &str) {
            self.u32(stamp_ns.div_euclid(1_000_000_000) as i32 as u32);
            self.u32(stamp_ns.rem_euclid(1_000_000_000) as u32);
            self.string(frame_id);
        }
    }

    /// `sensor_msgs/msg/JointState` with empty velocity and effort.
    pub fn joint_state(m: &JointStateMsg) -> Vec<u8> {
        let mut w = Writer::new();
        w.header(m.stamp.0, &m.frame_id);
        w.u32(m.name.len() as u32);
        for n in &m.name {
            w.string(n);
        }
        w.f64_seq(&m.position);
        w.f64_seq(&[]);
        w.f64_seq(&[]);
        w.out
    }

    /// The position and (x, y, z, w) quaternion of `m`.
    fn pose(w: &mut Writer, m: &PoseMsg) {
        let [qw, qx, qy, qz] = m.orientation;
        for x in m.position.into_iter().chain([qx, qy, qz, qw]) {
            w.f64(x);
        }
    }

    /// `geometry_msgs/msg/PoseStamped` (`child_frame_id` is not sent).
    pub fn pose_stamped(m: &PoseMsg) -> Vec<u8> {
        let mut w = Writer::new();
        w.header(m.stamp.0, &m.frame_id);
        pose(&mut w, m);
        w.out
    }

    /// `tf2_msgs/msg/TFMessage` of `transforms`.
    pub fn tf(transforms: &[PoseMsg]) -> Vec<u8> {
        let mut w = Writer::new();
        w.u32(transforms.len() as u32);
        for m in transforms {
            transform(&mut w, m);
        }
        w.out
    }

    /// `geometry_msgs/msg/TransformStamped`.
    pub fn transform_stamped(m: &PoseMsg) -> Vec<u8> {
        let mut w = Writer::new();
        transform(&mut w, m);
        w.out
    }

    fn transform(w: &mut Writer, m: &PoseMsg) {
        w.header(m.stamp.0, &m.frame_id);
        w.string(&m.child_frame_id);
        pose(w, m);
    }

    /// `sensor_msgs/msg/Imu` with identity orientation and zero covariances.
    pub fn imu(m: &ImuMsg) -> Vec<u8> {
        let mut w = Writer::new();
        w.header(m.stamp.0, &m.frame_id);
        for x in [0.0, 0.0, 0.0, 1.0] {
            w.f64(x);
        }
        let block = |w: &mut Writer, v: &[f64; 3]| {
            for &x in v {
                w.f64(x);
            }
            for _ in 0..9 {
                w.f64(0.0);
            }
        };
        for _ in 0..9 {
            w.f64(0.0);
        }
        block(&mut w, &m.angular_velocity);
        block(&mut w, &m.linear_acceleration);
        w.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A JointState derived by hand, byte by byte, big-endian CDR:
    /// stamp 5 s + 7 ns, frame "b", names ["j1"], position [1.5], velocity [],
    /// effort []. "rel" is the offset from the end of the header.
    ///
    /// ```text
    /// off  bytes                    field
    ///  0   00 00 00 00              encapsulation CDR_BE, options 0
    ///  4   00 00 00 05              stamp.sec = 5        (rel 0)
    ///  8   00 00 00 07              stamp.nanosec = 7    (rel 4)
    /// 12   00 00 00 02 62 00        frame_id "b": len 2, 'b', NUL (rel 8..14)
    /// 18   00 00                    pad to 4 (rel 14 → 16)
    /// 20   00 00 00 01              name count 1         (rel 16)
    /// 24   00 00 00 03 6a 31 00     "j1": len 3          (rel 20..27)
    /// 31   00                       pad to 4 (rel 27 → 28)
    /// 32   00 00 00 01              position count 1     (rel 28)
    /// 36   3f f8 00 .. 00           1.5 = 0x3FF8000000000000 (rel 32: aligned)
    /// 44   00 00 00 00              velocity count 0     (rel 40)
    /// 48   00 00 00 00              effort count 0       (rel 44)
    /// ```
    const JOINT_STATE_BE: [u8; 52] = [
        0x00, 0x00, 0x00, 0x00, // header
        0x00, 0x00, 0x00, 0x05, // sec
        0x00, 0x00, 0x00, 0x07, // nanosec
        0x00, 0x00, 0x00, 0x02, b'b', 0x00, // frame_id
        0x00, 0x00, // pad
        0x00, 0x00, 0x00, 0x01, // name count
        0x00, 0x00, 0x00, 0x03, b'j', b'1', 0x00, // "j1"
        0x00, // pad
        0x00, 0x00, 0x00, 0x01, // position count
        0x3f, 0xf8, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // 1.5
        0x00, 0x00, 0x00, 0x00, // velocity
        0x00, 0x00, 0x00, 0x00, // effort
    ];

    /// frame "abcde", no names, position [-2.0], little-endian: the position
    /// count ends at rel 28, so CDR pads 4 bytes before the float64 and CDR2
    /// (alignment at most 4) none.
    ///
    /// ```text
    ///  4   05 00 00 00 | 07 00 00 00   stamp (rel 0..8)
    /// 12   06 00 00 00 61..65 00       "abcde" (rel 8..18), pad 2 (→ rel 20)
    /// 24   00 00 00 00                 name count 0 (rel 20)
    /// 28   01 00 00 00                 position count 1 (rel 24..28)
    /// CDR:  32 pad 4, 36 -2.0 = 0xC000000000000000 LE, 44 vel 0, 48 effort 0
    /// CDR2: 32 -2.0, 40 vel 0, 44 effort 0
    /// ```
    fn padded(cdr2: bool) -> Vec<u8> {
        let mut b = vec![0x00, if cdr2 { 0x07 } else { 0x01 }, 0, 0];
        b.extend_from_slice(&[5, 0, 0, 0, 7, 0, 0, 0]);
        b.extend_from_slice(&[6, 0, 0, 0, b'a', b'b', b'c', b'd', b'e', 0, 0, 0]);
        b.extend_from_slice(&[0, 0, 0, 0, 1, 0, 0, 0]);
        if !cdr2 {
            b.extend_from_slice(&[0xAA; 4]); // padding: any value
        }
        b.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0xc0]);
        b.extend_from_slice(&[0; 8]);
        b
    }

    /// A PoseStamped derived by hand, little-endian CDR: stamp 3 s + 9 ns,
    /// frame "w", position (1, 2, 3), orientation x = 0, y = 0, z = 0.6,
    /// w = 0.8 ("rel": offset after the header).
    ///
    /// ```text
    ///  4   03 00 00 00 | 09 00 00 00   stamp (rel 0..8)
    /// 12   02 00 00 00 77 00           "w" (rel 8..14), pad 2 (→ rel 16)
    /// 20   1.0 2.0 3.0                 position (rel 16: aligned to 8)
    /// 44   0.0 0.0 0.6 0.8             orientation x, y, z, w (rel 40..72)
    /// ```
    fn pose_stamped_le() -> Vec<u8> {
        let mut b = vec![0x00, 0x01, 0, 0, 3, 0, 0, 0, 9, 0, 0, 0];
        b.extend_from_slice(&[2, 0, 0, 0, b'w', 0, 0, 0]);
        for x in [1.0f64, 2.0, 3.0, 0.0, 0.0, 0.6, 0.8] {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b
    }

    #[test]
    fn decodes_a_hand_derived_pose_stamped_and_a_tf_message() {
        let m = PoseMsg::decode_pose_stamped(&pose_stamped_le()).unwrap();
        assert_eq!(m.stamp, Stamp(3_000_000_009));
        assert_eq!(m.frame_id, "w");
        assert_eq!(m.position, [1.0, 2.0, 3.0]);
        // w first
        assert_eq!(m.orientation, [0.8, 0.0, 0.0, 0.6]);
        assert_eq!(encode::pose_stamped(&m), pose_stamped_le());
        // a TFMessage of two transforms: round trip, order kept
        let a = PoseMsg {
            child_frame_id: "tool0".into(),
            frame_id: "base".into(),
            ..m.clone()
        };
        let b = PoseMsg {
            stamp: Stamp(-1_500_000_000),
            position: [-0.5, 0.25, 1e-3],
            orientation: [0.0, 1.0, 0.0, 0.0],
            ..a.clone()
        };
        let bytes = encode::tf(&[a.clone(), b.clone()]);
        // a TFMessage is its count, then each TransformStamped's bytes
        let one = encode::transform_stamped(&b);
        assert_eq!(PoseMsg::decode_transform_stamped(&one).unwrap(), b);
        assert_eq!(bytes[bytes.len() - (one.len() - 4)..], one[4..]);
        assert_eq!(PoseMsg::decode_tf(&bytes).unwrap(), vec![a, b]);
        // truncated anywhere: an error naming it, never a panic
        for cut in 0..bytes.len() {
            assert!(PoseMsg::decode_tf(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let p = pose_stamped_le();
        for cut in 0..p.len() {
            assert!(PoseMsg::decode_pose_stamped(&p[..cut]).is_err());
        }
    }

    #[test]
    fn decodes_hand_derived_big_endian_joint_state() {
        let m = JointStateMsg::decode(&JOINT_STATE_BE).unwrap();
        assert_eq!(m.stamp, Stamp(5_000_000_007));
        assert_eq!(m.frame_id, "b");
        assert_eq!(m.name, vec!["j1".to_string()]);
        assert_eq!(m.position, vec![1.5]);
    }

    #[test]
    fn decodes_hand_derived_little_endian_and_cdr2() {
        // The same message little-endian: every multi-byte field reversed.
        let mut le = JOINT_STATE_BE;
        le[1] = 0x01;
        for range in [
            4..8,
            8..12,
            12..16,
            20..24,
            24..28,
            32..36,
            36..44,
            44..48,
            48..52,
        ] {
            le[range].reverse();
        }
        assert_eq!(JointStateMsg::decode(&le).unwrap().position, vec![1.5]);
        for cdr2 in [false, true] {
            let m = JointStateMsg::decode(&padded(cdr2)).unwrap();
            assert_eq!(m.frame_id, "abcde");
            assert!(m.name.is_empty());
            assert_eq!((m.position, m.stamp), (vec![-2.0], Stamp(5_000_000_007)));
        }
    }

    #[test]
    fn encoder_matches_the_hand_derived_layout_and_round_trips() {
        let m = JointStateMsg {
            stamp: Stamp(5_000_000_007),
            frame_id: "b".into(),
            name: vec!["j1".into()],
            position: vec![1.5],
        };
        let bytes = encode::joint_state(&m);
        // Same length and padding as the hand-derived big-endian bytes.
        assert_eq!(bytes.len(), JOINT_STATE_BE.len());
        assert_eq!(JointStateMsg::decode(&bytes).unwrap(), m);
        // Negative stamps (before the epoch) keep sec/nanosec semantics.
        let imu = ImuMsg {
            stamp: Stamp(-1),
            frame_id: "imu_link".into(),
            angular_velocity: [0.1, -0.2, 0.3],
            linear_acceleration: [9.81, 0.0, -1e-9],
        };
        let bytes = encode::imu(&imu);
        // header 4 + stamp 8 + "imu_link" 4+9 → rel 21, pad to 24, then
        // 4 + 9 + 3 + 9 + 3 + 9 = 37 float64.
        assert_eq!(bytes.len(), 4 + 24 + 37 * 8);
        assert_eq!(ImuMsg::decode(&bytes).unwrap(), imu);
    }

    #[test]
    fn bad_messages_name_the_cause() {
        for cut in [0, 3, 10, 30, 47, 51] {
            let e = JointStateMsg::decode(&JOINT_STATE_BE[..cut]).unwrap_err();
            // A cut inside a sequence's elements: its count is too long.
            assert!(
                matches!(e, CdrError::Truncated { .. } | CdrError::BadLength { .. }),
                "{cut}: {e}"
            );
        }
        let mut pl = JOINT_STATE_BE;
        pl[1] = 0x03; // PL_CDR_LE
        assert_eq!(
            JointStateMsg::decode(&pl).unwrap_err(),
            CdrError::Encapsulation(3)
        );
        let mut huge = JOINT_STATE_BE;
        huge[20..24].copy_from_slice(&[0x7f, 0xff, 0xff, 0xff]);
        assert!(matches!(
            JointStateMsg::decode(&huge),
            Err(CdrError::BadLength { offset: 20, .. })
        ));
        let mut no_nul = JOINT_STATE_BE;
        no_nul[17] = b'x';
        assert!(JointStateMsg::decode(&no_nul)
            .unwrap_err()
            .to_string()
            .contains("NUL"));
    }
}
