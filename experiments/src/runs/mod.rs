//! Runs as library calls: config → run folder.

pub mod inversion;
pub mod landscape;
