//! The problems the optimisers solve, each with its own data, model, objective and runner:
//! image → affine code by differentiable splatting ([`image`], any registered optimiser),
//! point cloud → similitude IFS by EM ([`em`], its own loop), texture upsampling by fractal
//! coding ([`fractal_coding`], a search, not an optimiser), image → segment pattern by the
//! differentiable SDF raster ([`sdf`], any registered optimiser), image → colour fractal
//! flame by the differentiable flame pipeline ([`flame`], any registered optimiser), pictures
//! around a 3-D fractal → a code of space ([`image3d`]). The SDF, flame and 3-D problems are
//! instances of the one image problem, [`render_problem::RenderProblem`].

pub mod em;
pub mod flame;
pub mod fractal_coding;
pub mod image;
pub mod image3d;
pub mod render_problem;
pub mod sdf;
