//! Generic optimisers: argmin `Solver`s over any [`crate::driver::Differentiable`] problem
//! (and [`annealing::Anneal`]'s cost for the value-only steps), each registered by name in
//! [`crate::registry`]. They know nothing of images, point clouds or textures.

pub mod adam;
pub mod annealing;
pub mod cmaes;
pub mod cuckoo;
pub mod evolutionary;
pub mod gd;
pub mod hybrid;
pub mod learning_fractals;
pub mod noisy;
pub mod swarm;
#[cfg(test)]
pub(crate) mod testing;
