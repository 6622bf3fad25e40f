//! no_std acquisition core (being built).
#![no_std]
