//! Simulated hardware (being built).
