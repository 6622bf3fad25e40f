//! The pipelines as the program runs them: the library call with its
//! progress line and printed output, shared by the commands that run it
//! (`calibrate` and `demo`; `diagnose` and `demo`). A command never imports
//! another command: what two share lives here or in the libraries.

pub mod calibrate;
pub mod demo;
pub mod diagnose;
pub mod poses;
