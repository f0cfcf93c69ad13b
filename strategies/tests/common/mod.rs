//! Helpers shared by the strategies' integration tests.

pub mod crisp_views;
