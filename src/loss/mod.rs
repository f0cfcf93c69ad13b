//! Image losses and regularisers, each with its gradient. Work in progress.
