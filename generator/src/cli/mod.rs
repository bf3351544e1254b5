//! The subcommands that read, check, measure or convert rather than generate: one file each.
//! `generate` itself is the output stage (`crate::output::generate`); `main.rs` parses the
//! command line and prints what these return.

pub mod bench;
pub mod dump;
pub mod export;
pub mod grasps;
pub mod inspect;
pub mod preview;
pub mod stats;
pub mod validate;
