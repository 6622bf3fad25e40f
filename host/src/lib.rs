//! robimu host library.
