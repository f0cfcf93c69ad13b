//! Fractal-coding texture upsampling (Kominami & Mukai). Work in progress.
