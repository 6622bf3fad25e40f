//! Register-level simulated BNO055 (being built).
#![no_std]
