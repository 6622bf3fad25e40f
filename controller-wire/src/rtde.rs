//! Universal Robots RTDE packages: big-endian `uint16 size` (including
//! this 3-byte header), `uint8 type`, payload, back to back on a TCP stream.

/// RTDE package types.
pub mod package {
    /// Request protocol version.
    pub const REQUEST_PROTOCOL_VERSION: u8 = b'V';
    /// Get the controller's software version (reply: major, minor, bugfix,
    /// build, each `uint32`).
    pub const GET_URCONTROL_VERSION: u8 = b'v';
    /// Text message from the controller.
    pub const TEXT_MESSAGE: u8 = b'M';
    /// Data package.
    pub const DATA_PACKAGE: u8 = b'U';
    /// Control package: setup outputs.
    pub const SETUP_OUTPUTS: u8 = b'O';
    /// Control package: start.
    pub const START: u8 = b'S';
    /// Control package: pause.
    pub const PAUSE: u8 = b'P';
}

/// Bytes of a package's header (size and type).
pub const HEADER: usize = 3;

/// A payload too long for a package's 16-bit size: the size it would need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooLong(pub usize);

/// The package of type `kind` carrying `payload`.
pub fn encode(kind: u8, payload: &[u8]) -> Result<Vec<u8>, TooLong> {
    let size = payload.len() + HEADER;
    let size16 = u16::try_from(size).map_err(|_| TooLong(size))?;
    let mut out = Vec::with_capacity(size);
    out.extend_from_slice(&size16.to_be_bytes());
    out.push(kind);
    out.extend_from_slice(payload);
    Ok(out)
}

/// A header whose size is less than the header itself: the stream cannot
/// be resynchronised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadSize(pub usize);

/// Incremental parser of the packages in a byte stream.
#[derive(Debug, Default)]
pub struct PackageParser {
    buf: Vec<u8>,
}

impl PackageParser {
    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete package's type and payload, `None` if more bytes
    /// are needed. A bad size discards the buffered bytes.
    pub fn next_package(&mut self) -> Result<Option<(u8, Vec<u8>)>, BadSize> {
        if self.buf.len() < HEADER {
            return Ok(None);
        }
        let size = u16::from_be_bytes([self.buf[0], self.buf[1]]) as usize;
        if size < HEADER {
            self.buf.clear();
            return Err(BadSize(size));
        }
        if self.buf.len() < size {
            return Ok(None);
        }
        let kind = self.buf[2];
        let payload = self.buf[HEADER..size].to_vec();
        self.buf.drain(..size);
        Ok(Some((kind, payload)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packages_round_trip_across_any_cut() {
        let mut bytes = encode(package::START, &[]).unwrap();
        bytes.extend(encode(package::DATA_PACKAGE, &[7, 1, 2, 3]).unwrap());
        assert_eq!(&bytes[..3], &[0, 3, b'S']);
        for cut in 0..bytes.len() {
            let mut p = PackageParser::default();
            let mut got = Vec::new();
            for part in [&bytes[..cut], &bytes[cut..]] {
                p.push(part);
                while let Some(pkg) = p.next_package().unwrap() {
                    got.push(pkg);
                }
            }
            assert_eq!(
                got,
                vec![(b'S', vec![]), (b'U', vec![7, 1, 2, 3])],
                "cut at {cut}"
            );
        }
    }

    #[test]
    fn bad_sizes_and_long_payloads_are_refused() {
        let mut p = PackageParser::default();
        p.push(&[0, 2, b'U', 0, 3, b'S']);
        assert_eq!(p.next_package(), Err(BadSize(2)));
        assert_eq!(p.next_package(), Ok(None));
        assert_eq!(encode(b'O', &[0; 65533]).unwrap_err(), TooLong(65536));
    }
}
