//! Cameras as data: a lens (pinhole or orthographic intrinsics, in pixels), a pose
//! (camera-to-world 4 × 4, the NeRF convention) and an image size; turntables of views
//! around the origin; NeRF-style `transforms.json` files.
//!
//! **Conventions** (NeRF's, i.e. OpenGL's): in camera coordinates `x` points right, `y` up
//! and the camera looks along `−z`; the pose's columns are the camera's right, up and back
//! axes and its position in world coordinates. Pixel coordinates are continuous, `u`
//! rightwards and `v` downwards, the centre of pixel `(i, j)` at `(i + ½, j + ½)` (the splat
//! kernel's convention), so a pinhole projects `(x, y, z)` (camera coordinates, `z < 0`) to
//! `u = c_x + f_x·x/(−z)`, `v = c_y − f_y·y/(−z)`, and an orthographic lens to
//! `u = c_x + f_x·x`, `v = c_y − f_y·y` (`f` in pixels per world unit). Turntables use
//! `+z` as the world's up, as NeRF's synthetic scenes do.

use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use serde_json::Value;

use crate::error::{Error, Result};

/// Points closer to a pinhole camera's plane than this (in world units, along the view
/// axis), or behind it, are not drawn.
pub const NEAR: f64 = 1e-3;

/// How much a pose's rotation may differ from an orthonormal matrix (`|RᵀR − I|` entry-wise;
/// poses written with single-precision floats pass).
const POSE_TOLERANCE: f64 = 1e-4;

/// A camera's intrinsics, in pixels of its image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lens {
    /// A pinhole: focal lengths and principal point in pixels.
    Pinhole {
        /// Focal length along `u`.
        fx: f64,
        /// Focal length along `v`.
        fy: f64,
        /// Principal point, `u`.
        cx: f64,
        /// Principal point, `v`.
        cy: f64,
    },
    /// A parallel projection: pixels per world unit along `u` and `v`, and where the view
    /// axis meets the image.
    Orthographic {
        /// Pixels per world unit along `u`.
        fx: f64,
        /// Pixels per world unit along `v`.
        fy: f64,
        /// Where the view axis meets the image, `u`.
        cx: f64,
        /// Where the view axis meets the image, `v`.
        cy: f64,
    },
}

impl Lens {
    /// A pinhole of horizontal field of view `fov_x` (radians) on a `width × height` image,
    /// square pixels, principal point at the centre (NeRF's `camera_angle_x`).
    pub fn pinhole_fov(fov_x: f64, width: usize, height: usize) -> Lens {
        let f = 0.5 * width as f64 / (0.5 * fov_x).tan();
        Lens::Pinhole {
            fx: f,
            fy: f,
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
        }
    }

    /// An orthographic lens showing `extent` world units across the width of a
    /// `width × height` image, centred.
    pub fn orthographic(extent: f64, width: usize, height: usize) -> Lens {
        let f = width as f64 / extent;
        Lens::Orthographic {
            fx: f,
            fy: f,
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
        }
    }

    fn numbers(&self) -> [f64; 4] {
        match *self {
            Lens::Pinhole { fx, fy, cx, cy } | Lens::Orthographic { fx, fy, cx, cy } => {
                [fx, fy, cx, cy]
            }
        }
    }
}

/// A camera: lens, pose and image size. Built by [`Camera::new`], which refuses a
/// degenerate one (see there); the world-to-camera transform is kept.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    lens: Lens,
    pose: [[f64; 4]; 4],
    width: usize,
    height: usize,
    /// World to camera: `p_c = rt·(p − eye)`, `rt` the transpose of the pose's rotation.
    rt: Matrix3<f64>,
    eye: Vector3<f64>,
}

impl Camera {
    /// A camera with `lens`, camera-to-world `pose` (rows) and a `width × height` image.
    ///
    /// Refuses (naming the defect) an empty image, non-finite or non-positive focal
    /// lengths, a non-finite principal point, a non-finite pose, a bottom row other than
    /// `(0, 0, 0, 1)`, and a rotation part that is not orthonormal or that mirrors
    /// (`det < 0`) — a scaled, sheared or singular pose is not a camera.
    pub fn new(lens: Lens, pose: [[f64; 4]; 4], width: usize, height: usize) -> Result<Camera> {
        if width == 0 || height == 0 {
            return Err(Error::Camera(format!(
                "the image is {width}×{height}; both sides must be at least 1 pixel"
            )));
        }
        let [fx, fy, cx, cy] = lens.numbers();
        if !(fx.is_finite() && fy.is_finite() && fx > 0.0 && fy > 0.0) {
            return Err(Error::Camera(format!(
                "focal lengths must be finite and > 0, got fx = {fx}, fy = {fy}"
            )));
        }
        if !(cx.is_finite() && cy.is_finite()) {
            return Err(Error::Camera(format!(
                "the principal point must be finite, got ({cx}, {cy})"
            )));
        }
        if let Some((r, c)) = (0..4)
            .flat_map(|r| (0..4).map(move |c| (r, c)))
            .find(|&(r, c)| !pose[r][c].is_finite())
        {
            return Err(Error::Camera(format!(
                "the pose holds a non-finite value ({}) at row {r}, column {c}",
                pose[r][c]
            )));
        }
        if pose[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(Error::Camera(format!(
                "the pose's bottom row must be (0, 0, 0, 1), got {:?}",
                pose[3]
            )));
        }
        let rot = Matrix3::from_fn(|r, c| pose[r][c]);
        let err = (rot.transpose() * rot - Matrix3::identity()).abs().max();
        if err > POSE_TOLERANCE {
            return Err(Error::Camera(format!(
                "the pose's rotation is not orthonormal (|RᵀR − I| = {err:.3e}); a camera-to-world \
                 pose has unit, perpendicular axes (no scale, shear or degenerate axis)"
            )));
        }
        if rot.determinant() < 0.0 {
            return Err(Error::Camera(
                "the pose's rotation mirrors (det < 0): its axes must be right-handed".into(),
            ));
        }
        Ok(Camera {
            lens,
            pose,
            width,
            height,
            rt: rot.transpose(),
            eye: Vector3::new(pose[0][3], pose[1][3], pose[2][3]),
        })
    }

    /// A camera at `eye` looking at `target`, rolled so that `up` points up in the image.
    /// Refuses `eye = target` and an `up` along the view direction.
    pub fn look_at(
        eye: [f64; 3],
        target: [f64; 3],
        up: [f64; 3],
        lens: Lens,
        width: usize,
        height: usize,
    ) -> Result<Camera> {
        let eye_v = Vector3::from(eye);
        let back = eye_v - Vector3::from(target);
        let dist = back.norm();
        if !(dist > 1e-12 && dist.is_finite()) {
            return Err(Error::Camera(format!(
                "the camera at {eye:?} cannot look at {target:?}: the points must differ"
            )));
        }
        let back = back / dist;
        let right = Vector3::from(up).cross(&back);
        let rn = right.norm();
        if !(rn > 1e-9 && rn.is_finite()) {
            return Err(Error::Camera(format!(
                "the up direction {up:?} is along the view direction: choose another up"
            )));
        }
        let right = right / rn;
        let cam_up = back.cross(&right);
        let mut pose = [[0.0; 4]; 4];
        for r in 0..3 {
            pose[r] = [right[r], cam_up[r], back[r], eye[r]];
        }
        pose[3] = [0.0, 0.0, 0.0, 1.0];
        Camera::new(lens, pose, width, height)
    }

    /// The lens.
    pub fn lens(&self) -> Lens {
        self.lens
    }

    /// Camera to world, rows.
    pub fn pose(&self) -> [[f64; 4]; 4] {
        self.pose
    }

    /// Image width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The camera's position in world coordinates.
    pub fn position(&self) -> [f64; 3] {
        [self.eye[0], self.eye[1], self.eye[2]]
    }

    /// `p` in camera coordinates.
    #[inline]
    pub fn to_camera(&self, p: [f64; 3]) -> [f64; 3] {
        let d = Vector3::from(p) - self.eye;
        let c = self.rt * d;
        [c[0], c[1], c[2]]
    }

    /// Where `p` (world coordinates) lands in the image, in pixels; `None` for a point
    /// behind a pinhole camera or within [`NEAR`] of its plane (orthographic cameras see
    /// everything).
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        let c = self.to_camera(p);
        match self.lens {
            Lens::Pinhole { fx, fy, cx, cy } => {
                let d = -c[2];
                (d > NEAR).then(|| [cx + fx * c[0] / d, cy - fy * c[1] / d])
            }
            Lens::Orthographic { fx, fy, cx, cy } => Some([cx + fx * c[0], cy - fy * c[1]]),
        }
    }

    /// [`Camera::project`] and its Jacobian `∂(u, v)/∂p` (2 × 3, rows `u`, `v`) with respect
    /// to the world point: `J_cam·Rᵀ`, with, for a pinhole at depth `d = −z`,
    /// `∂u/∂(x, y, z) = (f_x/d, 0, f_x·x/d²)` and `∂v/∂(x, y, z) = (0, −f_y/d, −f_y·y/d²)`.
    #[inline]
    pub fn project_with_jacobian(&self, p: [f64; 3]) -> Option<([f64; 2], [[f64; 3]; 2])> {
        let c = self.to_camera(p);
        let (uv, jc) = match self.lens {
            Lens::Pinhole { fx, fy, cx, cy } => {
                let d = -c[2];
                if d <= NEAR {
                    return None;
                }
                let id = 1.0 / d;
                (
                    [cx + fx * c[0] / d, cy - fy * c[1] / d],
                    [
                        [fx * id, 0.0, fx * c[0] * id * id],
                        [0.0, -fy * id, -fy * c[1] * id * id],
                    ],
                )
            }
            Lens::Orthographic { fx, fy, cx, cy } => (
                [cx + fx * c[0], cy - fy * c[1]],
                [[fx, 0.0, 0.0], [0.0, -fy, 0.0]],
            ),
        };
        // ∂(u, v)/∂p = J_cam · Rᵀ (rt is Rᵀ).
        let j = std::array::from_fn(|r| {
            std::array::from_fn(|k| (0..3).map(|m| jc[r][m] * self.rt[(m, k)]).sum())
        });
        Some((uv, j))
    }
}

/// `n` cameras on a circle around the `z` axis looking at the origin: azimuths
/// `360°·k/n` (`k = 0..n`, the first on the `+x` side), all at `elevation_deg` above the
/// `xy` plane and `distance` from the origin, `+z` up in every image. Refuses no view,
/// a non-positive distance and an elevation of ±90° or more (the up direction would be
/// the view direction).
pub fn turntable(
    n: usize,
    elevation_deg: f64,
    distance: f64,
    lens: Lens,
    width: usize,
    height: usize,
) -> Result<Vec<Camera>> {
    if n == 0 {
        return Err(Error::Camera("a turntable needs at least one view".into()));
    }
    if !(distance.is_finite() && distance > 0.0) {
        return Err(Error::Camera(format!(
            "the turntable's distance must be finite and > 0, got {distance}"
        )));
    }
    if !(elevation_deg.is_finite() && elevation_deg.abs() < 89.9) {
        return Err(Error::Camera(format!(
            "the turntable's elevation must lie strictly between −89.9° and 89.9°, got \
             {elevation_deg}°"
        )));
    }
    let e = elevation_deg.to_radians();
    (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            let eye = [
                distance * e.cos() * a.cos(),
                distance * e.cos() * a.sin(),
                distance * e.sin(),
            ];
            Camera::look_at(eye, [0.0; 3], [0.0, 0.0, 1.0], lens, width, height)
        })
        .collect()
}

/// One view of a `transforms.json`: the picture it names and its camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The frame's `file_path`, as written (NeRF's files leave the extension out).
    pub file_path: String,
    /// Its camera.
    pub camera: Camera,
}

/// Reads a NeRF-style `transforms.json` (see [`parse_transforms`]).
pub fn load_transforms(path: &Path, size: Option<(usize, usize)>) -> Result<Vec<Frame>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_transforms(&text, path, size)
}

/// Parses a NeRF-style `transforms.json`: a pinhole of horizontal field of view
/// `camera_angle_x` (radians; square pixels, centred principal point) shared by every
/// frame of `frames`, each with its `file_path` and its camera-to-world
/// `transform_matrix` (4 × 4 rows). instant-ngp's optional keys `fl_x`, `fl_y`, `cx`, `cy`,
/// `w`, `h` override the focal lengths, principal point and size; otherwise the image size
/// is `size` (that of the pictures), and a file giving neither is refused. `path` names the
/// file in messages; every refusal names the key or frame at fault.
pub fn parse_transforms(
    text: &str,
    path: &Path,
    size: Option<(usize, usize)>,
) -> Result<Vec<Frame>> {
    let fail = |message: String| Error::Parse {
        path: path.to_path_buf(),
        message,
    };
    let root: Value = serde_json::from_str(text).map_err(|e| fail(format!("not JSON: {e}")))?;
    let obj = root
        .as_object()
        .ok_or_else(|| fail("the top level must be an object".into()))?;
    let number = |key: &str| -> Result<Option<f64>> {
        match obj.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite())
                .map(Some)
                .ok_or_else(|| fail(format!("`{key}` must be a finite number, got {v}"))),
        }
    };
    let side = |key: &str| -> Result<Option<usize>> {
        match number(key)? {
            None => Ok(None),
            Some(x) if x >= 1.0 && x.fract() == 0.0 && x <= 1e6 => Ok(Some(x as usize)),
            Some(x) => Err(fail(format!(
                "`{key}` must be a whole number of pixels in 1..=1000000, got {x}"
            ))),
        }
    };
    let (width, height) = match (side("w")?, side("h")?, size) {
        (Some(w), Some(h), _) => (w, h),
        (None, None, Some(s)) => s,
        (w, h, Some(s)) => (w.unwrap_or(s.0), h.unwrap_or(s.1)),
        (_, _, None) => {
            return Err(fail(
                "the file gives no image size (`w` and `h`): pass the size of its pictures".into(),
            ));
        }
    };
    let fx = match (number("fl_x")?, number("camera_angle_x")?) {
        (Some(f), _) => f,
        (None, Some(a)) if a > 0.0 && a < std::f64::consts::PI => {
            0.5 * width as f64 / (0.5 * a).tan()
        }
        (None, Some(a)) => {
            return Err(fail(format!(
                "`camera_angle_x` must lie in (0, π) radians, got {a}"
            )));
        }
        (None, None) => {
            return Err(fail(
                "the file has no `camera_angle_x` (nor `fl_x`): the field of view is needed".into(),
            ));
        }
    };
    let lens = Lens::Pinhole {
        fx,
        fy: number("fl_y")?.unwrap_or(fx),
        cx: number("cx")?.unwrap_or(0.5 * width as f64),
        cy: number("cy")?.unwrap_or(0.5 * height as f64),
    };
    let frames = obj
        .get("frames")
        .ok_or_else(|| fail("the file has no `frames`".into()))?
        .as_array()
        .ok_or_else(|| fail("`frames` must be a list".into()))?;
    if frames.is_empty() {
        return Err(fail(
            "`frames` is empty: at least one view is needed".into(),
        ));
    }
    frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let file_path = match f.get("file_path") {
                Some(Value::String(s)) => s.clone(),
                Some(v) => {
                    return Err(fail(format!(
                        "frames[{i}].file_path must be a string, got {v}"
                    )));
                }
                None => return Err(fail(format!("frames[{i}] has no `file_path`"))),
            };
            let rows = f
                .get("transform_matrix")
                .ok_or_else(|| fail(format!("frames[{i}] has no `transform_matrix`")))?
                .as_array()
                .filter(|r| r.len() == 4)
                .ok_or_else(|| {
                    fail(format!(
                        "frames[{i}].transform_matrix must be a list of 4 rows"
                    ))
                })?;
            let mut pose = [[0.0; 4]; 4];
            for (r, row) in rows.iter().enumerate() {
                let row = row.as_array().filter(|v| v.len() == 4).ok_or_else(|| {
                    fail(format!(
                        "frames[{i}].transform_matrix row {r} must be a list of 4 numbers"
                    ))
                })?;
                for (c, v) in row.iter().enumerate() {
                    pose[r][c] = v.as_f64().ok_or_else(|| {
                        fail(format!(
                            "frames[{i}].transform_matrix[{r}][{c}] must be a number, got {v}"
                        ))
                    })?;
                }
            }
            let camera = Camera::new(lens, pose, width, height)
                .map_err(|e| fail(format!("frames[{i}] ({file_path}): {e}")))?;
            Ok(Frame { file_path, camera })
        })
        .collect()
}
