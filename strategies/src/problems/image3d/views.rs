//! The views a multi-view inversion fits: pictures with their cameras, read from a folder.
//!
//! A views folder holds PNG pictures (any size, all the same) and one of
//! - `transforms.json`, NeRF's camera file ([`ifslab::render::splat3d::load_transforms`]):
//!   each frame names its picture by `file_path`, relative to the folder, with or without
//!   the `.png` extension; or
//! - `turntable.json` ([`TurntableFile`]): N views on a circle at one elevation looking at
//!   the origin, `+z` up ([`turntable`]), through a pinhole of a given field of view or an
//!   orthographic lens; its `files` name the pictures in view order (by default every PNG
//!   of the folder, sorted by name).
//!
//! Each picture becomes a plane in [0, 1], ink 1 on a background 0, by the 2-D targets'
//! own reading ([`shape_plane`]: opacity, or luma oriented by its border); no framing — the
//! cameras fix where the attractor is. [`write_views`] writes a folder of the library's own
//! renders (the multi-view splat of a code) in the same form.

use std::path::{Path, PathBuf};

use ifslab::image::Image;
use ifslab::model::map3::SvdMap3;
use ifslab::render::Renderer;
use ifslab::render::splat3d::{
    Camera, Lens, MultiViewConfig, MultiViewSplat, load_transforms, turntable,
};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::image::target::{Polarity, shape_plane};

/// The name of a NeRF-style camera file in a views folder.
pub const TRANSFORMS_FILE: &str = "transforms.json";
/// The name of a turntable description in a views folder.
pub const TURNTABLE_FILE: &str = "turntable.json";

/// A turntable description (`turntable.json`): `views` cameras at `elevation_deg` above
/// the `xy` plane and `distance` from the origin, looking at it, the first on the `+x`
/// side; a pinhole of horizontal field of view `fov_x_deg`, or an orthographic lens showing
/// `orthographic_extent` world units across (exactly one of the two).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableFile {
    /// Number of views.
    pub views: usize,
    /// Elevation in degrees, strictly between −89.9 and 89.9.
    pub elevation_deg: f64,
    /// Distance of every camera from the origin.
    pub distance: f64,
    /// A pinhole's horizontal field of view in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_x_deg: Option<f64>,
    /// An orthographic lens: world units across the image's width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orthographic_extent: Option<f64>,
    /// The pictures in view order, relative to the folder (default: every PNG, by name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<Vec<String>>,
}

impl TurntableFile {
    /// The cameras for pictures of `width × height`; refuses a missing or doubled lens and
    /// what [`turntable`] refuses.
    pub fn cameras(&self, width: usize, height: usize) -> Result<Vec<Camera>> {
        let lens = match (self.fov_x_deg, self.orthographic_extent) {
            (Some(fov), None) if fov.is_finite() && fov > 0.0 && fov < 180.0 => {
                Lens::pinhole_fov(fov.to_radians(), width, height)
            }
            (Some(fov), None) => {
                return Err(Error::param(
                    "fov_x_deg",
                    format!("must lie strictly between 0 and 180 degrees, got {fov}"),
                ));
            }
            (None, Some(e)) if e.is_finite() && e > 0.0 => Lens::orthographic(e, width, height),
            (None, Some(e)) => {
                return Err(Error::param(
                    "orthographic_extent",
                    format!("must be finite and > 0, got {e}"),
                ));
            }
            _ => {
                return Err(Error::param(
                    "fov_x_deg",
                    "give exactly one of `fov_x_deg` (a pinhole) and `orthographic_extent`",
                ));
            }
        };
        Ok(turntable(
            self.views,
            self.elevation_deg,
            self.distance,
            lens,
            width,
            height,
        )?)
    }
}

/// Pictures with their cameras: the targets of a multi-view inversion.
#[derive(Clone, Debug)]
pub struct Views {
    /// One camera per view, all with the pictures' size.
    pub cameras: Vec<Camera>,
    /// The pictures, one plane per view (ink 1, values in [0, 1]): the image the multi-view
    /// splat draws, plane after plane.
    pub image: Image,
    /// Where each picture was read from (empty for views made in memory).
    pub files: Vec<PathBuf>,
}

impl Views {
    /// Views from `cameras` and `image`, its plane `i` the picture camera `i` sees; refuses
    /// no camera, cameras of different sizes, an image that is not one plane of their size
    /// per camera, and values that are not finite.
    pub fn new(cameras: Vec<Camera>, image: Image) -> Result<Views> {
        let (w, h) = check_cameras(&cameras)?;
        let views = u32::try_from(cameras.len())
            .map_err(|_| Error::InvalidInput(format!("{} views are too many", cameras.len())))?;
        image.expect_shape("the views' image", views, w, h)?;
        if let Some(i) = image.values.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "view {} holds a non-finite value",
                i / (w * h)
            )));
        }
        Ok(Views {
            cameras,
            image,
            files: Vec::new(),
        })
    }

    /// A fingerprint of the views (FNV-1a, 64 bits, in hex) over every camera — its lens,
    /// pose and size — and every plane's values: what a resumed run checks it fits the
    /// pictures it started on.
    pub fn digest(&self) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bytes: &[u8]| {
            for &b in bytes {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        for c in &self.cameras {
            eat(format!("{:?}", c.lens()).as_bytes());
            for row in c.pose() {
                row.iter().for_each(|v| eat(&v.to_bits().to_le_bytes()));
            }
            eat(&(c.width() as u64).to_le_bytes());
            eat(&(c.height() as u64).to_le_bytes());
        }
        self.image
            .values
            .iter()
            .for_each(|v| eat(&v.to_bits().to_le_bytes()));
        format!("{h:016x}")
    }

    /// Number of views.
    pub fn len(&self) -> usize {
        self.cameras.len()
    }

    /// Whether there is no view (never, for views that were checked).
    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }

    /// Width and height of every view.
    pub fn size(&self) -> (usize, usize) {
        (self.cameras[0].width(), self.cameras[0].height())
    }

    /// View `i`'s plane.
    pub fn plane(&self, i: usize) -> &[f32] {
        self.image.plane(i)
    }

    /// The views at `indices` (in that order); refuses an empty list and an index past
    /// the last view.
    pub fn subset(&self, indices: &[usize]) -> Result<Views> {
        if let Some(&i) = indices.iter().find(|&&i| i >= self.len()) {
            return Err(Error::InvalidInput(format!(
                "view {i} asked for, but there are {} views",
                self.len()
            )));
        }
        let mut planes = Vec::with_capacity(indices.len() * self.plane(0).len());
        for &i in indices {
            planes.extend_from_slice(self.plane(i));
        }
        let (w, h) = self.size();
        let mut out = Views::new(
            indices.iter().map(|&i| self.cameras[i].clone()).collect(),
            Image::new(w as u32, h as u32, indices.len() as u32, planes)?,
        )?;
        if self.files.len() == self.len() {
            out.files = indices.iter().map(|&i| self.files[i].clone()).collect();
        }
        Ok(out)
    }

    /// `k` views spread evenly around the list (indices `⌊(j + ½)·n/k⌋`, `j < k`), held
    /// out of a fit to score it on views it did not see, and the others; refuses `k` that
    /// leaves fewer than one view to fit.
    pub fn hold_out(&self, k: usize) -> Result<(Vec<usize>, Vec<usize>)> {
        let n = self.len();
        if k >= n {
            return Err(Error::param(
                "hold_out",
                format!("{k} held-out views leave none of the {n} views to fit"),
            ));
        }
        let held: Vec<usize> = (0..k).map(|j| ((2 * j + 1) * n) / (2 * k)).collect();
        let fit = (0..n).filter(|i| !held.contains(i)).collect();
        Ok((fit, held))
    }
}

/// The common size of `cameras`; refuses none and different sizes, naming the view.
fn check_cameras(cameras: &[Camera]) -> Result<(usize, usize)> {
    let Some(first) = cameras.first() else {
        return Err(Error::InvalidInput(
            "no view: a multi-view inversion needs at least one picture with its camera".into(),
        ));
    };
    let (w, h) = (first.width(), first.height());
    for (i, c) in cameras.iter().enumerate() {
        if (c.width(), c.height()) != (w, h) {
            return Err(Error::InvalidInput(format!(
                "view {i} is {}×{} but view 0 is {w}×{h}: every view must have the same size",
                c.width(),
                c.height()
            )));
        }
    }
    Ok((w, h))
}

/// Reads a views folder (see the module docs). Refuses a missing folder, one with neither
/// or both camera files, no picture, a missing or unreadable picture, pictures of different
/// sizes, and every camera [`load_transforms`] or [`turntable`] refuses (degenerate poses,
/// NaN), naming the file or frame.
pub fn load_views(dir: &Path) -> Result<Views> {
    if !dir.is_dir() {
        return Err(Error::file(
            dir,
            "not a folder: give the folder holding the views' PNGs and their transforms.json or \
             turntable.json",
        ));
    }
    let transforms = dir.join(TRANSFORMS_FILE);
    let table = dir.join(TURNTABLE_FILE);
    match (transforms.is_file(), table.is_file()) {
        (true, true) => Err(Error::file(
            dir,
            "holds both transforms.json and turntable.json: keep the one that describes the \
             cameras",
        )),
        (false, false) => Err(Error::file(
            dir,
            "has no cameras: add a transforms.json (NeRF-style) or a turntable.json",
        )),
        (true, false) => load_nerf(dir, &transforms),
        (false, true) => load_turntable(dir, &table),
    }
}

fn load_nerf(dir: &Path, path: &Path) -> Result<Views> {
    // The size is that of the pictures: the first frame's, when the file names one (a file
    // that does not is refused by `load_transforms`, which says why).
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let first = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v["frames"][0]["file_path"].as_str().map(str::to_owned));
    let size = match first {
        Some(name) => Some(picture_size(&picture_path(dir, &name)?)?),
        None => None,
    };
    let frames = load_transforms(path, size)?;
    let files = frames
        .iter()
        .map(|f| picture_path(dir, &f.file_path))
        .collect::<Result<Vec<_>>>()?;
    let cameras = frames.into_iter().map(|f| f.camera).collect();
    read_pictures(cameras, files)
}

fn load_turntable(dir: &Path, path: &Path) -> Result<Views> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let spec: TurntableFile =
        serde_json::from_str(&text).map_err(|e| Error::file(path, format!("{e}")))?;
    let files: Vec<PathBuf> = match &spec.files {
        Some(names) => names
            .iter()
            .map(|n| picture_path(dir, n))
            .collect::<Result<_>>()?,
        None => {
            let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
                .map_err(|e| Error::file(dir, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("png")))
                .collect();
            found.sort();
            found
        }
    };
    if files.is_empty() {
        return Err(Error::file(dir, "holds no PNG picture: no view to fit"));
    }
    if files.len() != spec.views {
        return Err(Error::file(
            path,
            format!(
                "describes {} views but {} pictures were found: give one picture per view",
                spec.views,
                files.len()
            ),
        ));
    }
    let (w, h) = picture_size(&files[0])?;
    let cameras = spec
        .cameras(w, h)
        .map_err(|e| Error::file(path, e.to_string()))?;
    read_pictures(cameras, files)
}

/// The picture a frame names: the path as written, else with `.png` added; refuses one
/// that does not exist.
fn picture_path(dir: &Path, name: &str) -> Result<PathBuf> {
    let p = dir.join(name);
    if p.is_file() {
        return Ok(p);
    }
    let with_png = dir.join(format!("{name}.png"));
    if with_png.is_file() {
        return Ok(with_png);
    }
    Err(Error::file(
        &p,
        "the picture of this view is missing (looked for it as written and with .png)",
    ))
}

fn picture_size(path: &Path) -> Result<(usize, usize)> {
    let img = Image::load_rgba(path)?;
    Ok((img.width as usize, img.height as usize))
}

/// Reads every picture as a shape plane, in view order; refuses sizes that differ from the
/// cameras'.
fn read_pictures(cameras: Vec<Camera>, files: Vec<PathBuf>) -> Result<Views> {
    let (w, h) = check_cameras(&cameras)?;
    let mut planes = Vec::with_capacity(cameras.len() * w * h);
    for (i, f) in files.iter().enumerate() {
        let img = Image::load_rgba(f)?;
        if (img.width as usize, img.height as usize) != (w, h) {
            return Err(Error::file(
                f,
                format!(
                    "view {i} is {}×{} but the views are {w}×{h}: every picture must have the \
                     same size",
                    img.width, img.height
                ),
            ));
        }
        let (plane, _) =
            shape_plane(&img, Polarity::Auto).map_err(|e| Error::file(f, e.to_string()))?;
        planes.extend_from_slice(&plane);
    }
    let n = cameras.len() as u32;
    let mut views = Views::new(cameras, Image::new(w as u32, h as u32, n, planes)?)?;
    views.files = files;
    Ok(views)
}

/// The multi-view splat's image of `maps` through `cameras` (one plane per camera, ink 1),
/// drawn with `render`, map `i` with probability `probs[i]` (uniform when `None`), and the
/// chaos-game seed `seed`.
pub fn render_views(
    maps: &[SvdMap3],
    cameras: &[Camera],
    render: &MultiViewConfig,
    probs: Option<&[f64]>,
    seed: u64,
) -> Result<Image> {
    let splat = MultiViewSplat::<SvdMap3, f32>::new(render.clone(), cameras.to_vec())?
        .with_probabilities(probs.map(<[f64]>::to_vec));
    let sampling = splat.sampling(maps, seed, 0);
    let planes = splat.forward(maps, &sampling)?.0;
    let (w, h) = check_cameras(cameras)?;
    Ok(Image::new(
        w as u32,
        h as u32,
        cameras.len() as u32,
        planes,
    )?)
}

/// Writes a views folder: `views`' planes (ink 1, one per view) as `view_000.png`, … —
/// dark ink on white — and `spec` as its `turntable.json` (with the files named). The
/// cameras are `spec`'s at the planes' size.
pub fn write_views(dir: &Path, spec: &TurntableFile, views: &Image) -> Result<()> {
    let (width, height) = (views.width as usize, views.height as usize);
    let n = u32::try_from(spec.views).map_err(|_| Error::param("views", "too many"))?;
    views.expect_shape("the views' image", n, width, height)?;
    let planes = &views.values;
    spec.cameras(width, height)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
    let mut names = Vec::with_capacity(spec.views);
    for (i, plane) in planes.chunks_exact(width * height).enumerate() {
        let name = format!("view_{i:03}.png");
        let paper: Vec<f32> = plane.iter().map(|v| 1.0 - v.clamp(0.0, 1.0)).collect();
        Image::grey(width as u32, height as u32, paper)?.save_png(&dir.join(&name))?;
        names.push(name);
    }
    let spec = TurntableFile {
        files: Some(names),
        ..spec.clone()
    };
    let text = serde_json::to_string_pretty(&spec)
        .map_err(|e| Error::Numerical(format!("turntable.json: {e}")))?;
    ifslab::io::write_atomic(&dir.join(TURNTABLE_FILE), text.as_bytes())?;
    Ok(())
}
