//! Integration tests live in `tests/`.

#![deny(missing_docs)]
