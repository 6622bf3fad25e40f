//! What robimu's robot controller clients (`robimu-record`) and its
//! simulated controllers (`robimu-hil-sim`) share, defined once:
//!
//! * [`json_stream`]: AUBO ARCS JSON-RPC's byte stream of bare,
//!   concatenated JSON objects, parsed incrementally.
//! * [`rtde`]: Universal Robots RTDE packages (`uint16 size`, `uint8
//!   type`, payload): their types, encoding and incremental parsing.
//! * [`pace`]: a loop run at a fixed rate (joint polling, simulation steps).
#![deny(missing_docs)]

pub mod json_stream;
pub mod pace;
pub mod rtde;

pub use json_stream::StreamParser;
pub use pace::Pacer;
