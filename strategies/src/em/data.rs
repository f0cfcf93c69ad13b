//! Point clouds for EM: an N×H row-major array of finite numbers, loaded from CSV / text
//! or NumPy `.npy` files, validated row by row, split into training and held-out parts.
//!
//! Text files hold one point per line, numbers separated by commas, semicolons, tabs or
//! spaces; blank lines and lines starting with `#` are skipped, and a first line that is
//! not numeric is taken as a header. `.npy` files hold a 1-D (N points in 1-D) or 2-D
//! (N×H) array of floats or integers, little- or big-endian, C or Fortran order; the
//! reader is written here (the format is a short ASCII header and a raw buffer) rather
//! than pulling in `ndarray-npy`, which would bring a second array stack into a crate
//! built on nalgebra.
//!
//! Every malformed input gets an error naming the file, the line (or row) and what to fix:
//! a number that does not parse, rows of different dimensions, NaN or infinite values.
//!
//! ## References
//! - NumPy enhancement proposal NEP 1, *A simple file format for NumPy arrays*.

use std::path::Path;

use rand::seq::SliceRandom;
use rayon::prelude::*;

use crate::error::{Error, Result};

/// N points in R^H, stored row-major (`data[i·H + j]` is coordinate j of point i).
#[derive(Clone, Debug, PartialEq)]
pub struct PointSet {
    dim: usize,
    data: Vec<f64>,
}

impl PointSet {
    /// A point set from a flat row-major buffer; checks the shape and that every value is
    /// finite (the error names the first bad row).
    pub fn new(dim: usize, data: Vec<f64>) -> Result<Self> {
        if dim == 0 {
            return Err(Error::InvalidInput(
                "points must have at least one coordinate (dimension 0 given)".into(),
            ));
        }
        if !data.len().is_multiple_of(dim) {
            return Err(Error::InvalidInput(format!(
                "a buffer of {} numbers does not split into points of dimension {dim}",
                data.len()
            )));
        }
        if let Some(pos) = data.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "point {} has a non-finite coordinate ({}); remove or fix NaN/infinite rows",
                pos / dim,
                data[pos]
            )));
        }
        Ok(PointSet { dim, data })
    }

    /// A point set from rows that must all have the same length.
    pub fn from_rows(rows: &[Vec<f64>]) -> Result<Self> {
        let dim = rows
            .first()
            .map(Vec::len)
            .ok_or_else(|| Error::InvalidInput("no points given".into()))?;
        if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != dim) {
            return Err(Error::InvalidInput(format!(
                "point {i} has {} coordinates but point 0 has {dim}; all points need the same dimension",
                r.len()
            )));
        }
        PointSet::new(dim, rows.concat())
    }

    /// Dimension H.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of points N.
    pub fn len(&self) -> usize {
        self.data.len() / self.dim
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Point `i` as a slice of H numbers.
    pub fn point(&self, i: usize) -> &[f64] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// The flat row-major buffer.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// Iterator over the points.
    pub fn iter(&self) -> std::slice::ChunksExact<'_, f64> {
        self.data.chunks_exact(self.dim)
    }

    /// The points with the given indices, in that order.
    pub fn select(&self, indices: &[usize]) -> PointSet {
        let mut data = Vec::with_capacity(indices.len() * self.dim);
        for &i in indices {
            data.extend_from_slice(self.point(i));
        }
        PointSet {
            dim: self.dim,
            data,
        }
    }

    /// The first `n` points (all of them when `n ≥ N`).
    pub fn head(&self, n: usize) -> PointSet {
        let n = n.min(self.len());
        PointSet {
            dim: self.dim,
            data: self.data[..n * self.dim].to_vec(),
        }
    }

    /// A seeded shuffle split: `(train, held_out)` with `round(fraction·N)` held-out points
    /// (at least one of each when `0 < fraction < 1` and N ≥ 2).
    pub fn split(&self, fraction: f64, seed: u64) -> Result<(PointSet, PointSet)> {
        if !(0.0..1.0).contains(&fraction) {
            return Err(Error::param(
                "heldout",
                format!("held-out fraction must lie in [0, 1), got {fraction}"),
            ));
        }
        let n = self.len();
        let mut idx: Vec<usize> = (0..n).collect();
        let mut rng = ifslab::chaos::trajectory_rng(seed, 0x5e1f);
        idx.shuffle(&mut rng);
        let mut n_test = (fraction * n as f64).round() as usize;
        if fraction > 0.0 && n >= 2 {
            n_test = n_test.clamp(1, n - 1);
        }
        let test = self.select(&idx[..n_test]);
        let train = self.select(&idx[n_test..]);
        Ok((train, test))
    }

    /// Per-coordinate mean.
    pub fn mean(&self) -> Vec<f64> {
        let mut m = vec![0.0; self.dim];
        for p in self.iter() {
            for (a, b) in m.iter_mut().zip(p) {
                *a += b;
            }
        }
        let n = self.len().max(1) as f64;
        m.iter_mut().for_each(|v| *v /= n);
        m
    }

    /// Root-mean-square distance of the points to their mean.
    pub fn rms_radius(&self) -> f64 {
        let m = self.mean();
        let ss: f64 = self
            .iter()
            .map(|p| {
                p.iter()
                    .zip(&m)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
            })
            .sum();
        (ss / self.len().max(1) as f64).sqrt()
    }

    /// Principal axes of the points (unit vectors, largest variance first): what a 2-D view
    /// of higher-dimensional points projects onto.
    pub fn principal_axes(&self) -> Vec<Vec<f64>> {
        let h = self.dim;
        let m = self.mean();
        let mut cov = nalgebra::DMatrix::<f64>::zeros(h, h);
        for p in self.iter() {
            for i in 0..h {
                for j in 0..h {
                    cov[(i, j)] += (p[i] - m[i]) * (p[j] - m[j]);
                }
            }
        }
        let eig = cov.symmetric_eigen();
        let mut order: Vec<usize> = (0..h).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        order
            .iter()
            .map(|&c| eig.eigenvectors.column(c).iter().copied().collect())
            .collect()
    }

    /// Loads a point cloud: `.npy` by its magic bytes or extension, anything else as text.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
        let is_npy = bytes.starts_with(NPY_MAGIC)
            || path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if is_npy {
            parse_npy(&bytes, path)
        } else {
            let text = std::str::from_utf8(&bytes).map_err(|_| {
                Error::file(
                    path,
                    "not UTF-8 text and not a .npy file; give a CSV/text file or a NumPy .npy array",
                )
            })?;
            parse_text(text, path)
        }
    }

    /// The points as CSV text (`x0,x1,…` per line, shortest round-trip formatting).
    pub fn to_csv(&self) -> String {
        let mut s = String::with_capacity(self.data.len() * 20);
        let header: Vec<String> = (0..self.dim).map(|j| format!("x{j}")).collect();
        s.push_str(&header.join(","));
        s.push('\n');
        for p in self.iter() {
            let row: Vec<String> = p.iter().map(|v| format!("{v}")).collect();
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }

    /// The points as a little-endian `float64` `.npy` file (format version 1.0).
    pub fn to_npy(&self) -> Vec<u8> {
        let dict = format!(
            "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {}), }}",
            self.len(),
            self.dim
        );
        // Magic (6) + version (2) + header length (2) + header, padded to 64 bytes with '\n' last.
        let unpadded = 10 + dict.len() + 1;
        let pad = (64 - unpadded % 64) % 64;
        let mut header = dict.into_bytes();
        header.extend(std::iter::repeat_n(b' ', pad));
        header.push(b'\n');
        let mut out = Vec::with_capacity(10 + header.len() + self.data.len() * 8);
        out.extend_from_slice(NPY_MAGIC);
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(&header);
        for v in &self.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Writes the points atomically as `.npy` (by extension) or CSV.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let bytes = if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
        {
            self.to_npy()
        } else {
            self.to_csv().into_bytes()
        };
        ifslab::io::write_atomic(path, &bytes).map_err(Error::from)
    }
}

/// Parses delimited text (see the module docs); `origin` names the source in errors.
pub fn parse_text(text: &str, origin: &Path) -> Result<PointSet> {
    let mut dim = 0usize;
    let mut first_line = 0usize;
    let mut data = Vec::new();
    let mut seen_data = false;
    for (lineno, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let parsed: std::result::Result<Vec<f64>, _> =
            fields.iter().map(|f| f.parse::<f64>()).collect();
        let values = match parsed {
            Ok(v) => v,
            Err(_) if !seen_data && data.is_empty() && dim == 0 && first_line == 0 => {
                // A header line: remember that we skipped it, only once.
                first_line = lineno + 1;
                continue;
            }
            Err(_) => {
                let bad = fields
                    .iter()
                    .position(|f| f.parse::<f64>().is_err())
                    .unwrap_or(0);
                return Err(Error::file(
                    origin,
                    format!(
                        "line {}: field {} (`{}`) is not a number; every data line must hold numbers only",
                        lineno + 1,
                        bad + 1,
                        fields[bad]
                    ),
                ));
            }
        };
        if !seen_data {
            dim = values.len();
            seen_data = true;
        } else if values.len() != dim {
            return Err(Error::file(
                origin,
                format!(
                    "line {}: {} values, but earlier lines have {dim}; every point must have the same dimension",
                    lineno + 1,
                    values.len()
                ),
            ));
        }
        if let Some(j) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::file(
                origin,
                format!(
                    "line {}: coordinate {} is {}; remove or repair rows with NaN or infinite values",
                    lineno + 1,
                    j + 1,
                    values[j]
                ),
            ));
        }
        data.extend(values);
    }
    if !seen_data {
        return Err(Error::file(
            origin,
            "no data lines (the file is empty or only a header)",
        ));
    }
    PointSet::new(dim, data).map_err(|e| Error::file(origin, e))
}

const NPY_MAGIC: &[u8] = b"\x93NUMPY";

/// Element types the `.npy` reader understands.
#[derive(Clone, Copy, Debug)]
enum NpyType {
    F64,
    F32,
    I64,
    I32,
    I16,
    I8,
    U64,
    U32,
    U16,
    U8,
}

impl NpyType {
    fn size(self) -> usize {
        match self {
            NpyType::F64 | NpyType::I64 | NpyType::U64 => 8,
            NpyType::F32 | NpyType::I32 | NpyType::U32 => 4,
            NpyType::I16 | NpyType::U16 => 2,
            NpyType::I8 | NpyType::U8 => 1,
        }
    }

    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! rd {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            NpyType::F64 => rd!(f64, 8),
            NpyType::F32 => rd!(f32, 4),
            NpyType::I64 => rd!(i64, 8),
            NpyType::I32 => rd!(i32, 4),
            NpyType::I16 => rd!(i16, 2),
            NpyType::I8 => b[0] as i8 as f64,
            NpyType::U64 => rd!(u64, 8),
            NpyType::U32 => rd!(u32, 4),
            NpyType::U16 => rd!(u16, 2),
            NpyType::U8 => b[0] as f64,
        }
    }
}

/// Parses a `.npy` buffer (format versions 1, 2 and 3); `origin` names the file in errors.
pub fn parse_npy(bytes: &[u8], origin: &Path) -> Result<PointSet> {
    let bad = |m: String| Error::file(origin, m);
    if !bytes.starts_with(NPY_MAGIC) || bytes.len() < 10 {
        return Err(bad(
            "not a NumPy .npy file (missing the \\x93NUMPY magic bytes)".into(),
        ));
    }
    let major = bytes[6];
    let (hlen, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(bad("truncated .npy header".into()));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => {
            return Err(bad(format!(
                ".npy format version {v} is not supported (1–3 are)"
            )));
        }
    };
    let header = bytes
        .get(start..start + hlen)
        .ok_or_else(|| bad("truncated .npy header".into()))?;
    let header = std::str::from_utf8(header).map_err(|_| bad(".npy header is not text".into()))?;
    let descr = dict_value(header, "descr")
        .ok_or_else(|| bad(format!("header has no 'descr': {header}")))?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let fortran = dict_value(header, "fortran_order")
        .map(|v| v.trim().starts_with("True"))
        .unwrap_or(false);
    let shape_txt = dict_value(header, "shape")
        .ok_or_else(|| bad(format!("header has no 'shape': {header}")))?;
    let shape: Vec<usize> = shape_txt
        .trim()
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad(format!("cannot read the shape {shape_txt}")))?;
    let (n, h) = match shape.as_slice() {
        [n] => (*n, 1),
        [n, h] => (*n, *h),
        other => {
            return Err(bad(format!(
                "array has shape {other:?}; a point cloud must be 1-D (N) or 2-D (N×H)"
            )));
        }
    };
    let (big, code) = match descr.as_bytes().first() {
        Some(b'<') | Some(b'|') | Some(b'=') => (false, &descr[1..]),
        Some(b'>') => (true, &descr[1..]),
        _ => (false, descr),
    };
    let ty = match code {
        "f8" => NpyType::F64,
        "f4" => NpyType::F32,
        "i8" => NpyType::I64,
        "i4" => NpyType::I32,
        "i2" => NpyType::I16,
        "i1" => NpyType::I8,
        "u8" => NpyType::U64,
        "u4" => NpyType::U32,
        "u2" => NpyType::U16,
        "u1" | "b1" => NpyType::U8,
        other => {
            return Err(bad(format!(
                "element type `{other}` is not supported; save the array as float64 (`arr.astype('f8')`)"
            )));
        }
    };
    let body = &bytes[start + hlen..];
    let need = n
        .checked_mul(h)
        .and_then(|c| c.checked_mul(ty.size()))
        .ok_or_else(|| bad("array shape overflows".into()))?;
    if body.len() < need {
        return Err(bad(format!(
            "data is truncated: the shape needs {need} bytes, the file has {}",
            body.len()
        )));
    }
    if n == 0 || h == 0 {
        return Err(bad(format!("array is empty (shape {shape:?})")));
    }
    let sz = ty.size();
    let mut data = vec![0.0; n * h];
    data.par_chunks_mut(h).enumerate().for_each(|(i, row)| {
        for (j, v) in row.iter_mut().enumerate() {
            // C order: element (i, j) at i·h + j; Fortran order: at j·n + i.
            let e = if fortran { j * n + i } else { i * h + j };
            *v = ty.read(&body[e * sz..(e + 1) * sz], big);
        }
    });
    if let Some(pos) = data.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!(
            "row {} has a non-finite coordinate ({}); remove or repair rows with NaN or infinite values",
            pos / h,
            data[pos]
        )));
    }
    PointSet::new(h, data).map_err(|e| Error::file(origin, e))
}

/// The text of `key`'s value in a Python dict literal, up to the next top-level comma.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat1 = format!("'{key}'");
    let pat2 = format!("\"{key}\"");
    let at = header.find(&pat1).or_else(|| header.find(&pat2))?;
    let rest = &header[at + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0i32;
    for (i, c) in rest.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    Some(rest)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_with_header_comments_and_mixed_separators() {
        let t = "x,y\n# comment\n1,2\n3;4\n5 6\n\n";
        let p = parse_text(t, Path::new("t.csv")).unwrap();
        assert_eq!(p.dim(), 2);
        assert_eq!(p.as_slice(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn npy_round_trip_and_fortran_order() {
        let p = PointSet::new(3, (0..12).map(|v| v as f64 * 0.5).collect()).unwrap();
        let back = parse_npy(&p.to_npy(), Path::new("a.npy")).unwrap();
        assert_eq!(back, p);
        // A hand-made Fortran-order int32 array of shape (2, 3): columns stored first.
        let dict = "{'descr': '<i4', 'fortran_order': True, 'shape': (2, 3), }";
        let mut b = NPY_MAGIC.to_vec();
        b.extend_from_slice(&[1, 0]);
        b.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        b.extend_from_slice(dict.as_bytes());
        for v in [1i32, 4, 2, 5, 3, 6] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let f = parse_npy(&b, Path::new("f.npy")).unwrap();
        assert_eq!(f.as_slice(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn split_is_seeded_and_disjoint() {
        let p = PointSet::new(1, (0..100).map(f64::from).collect()).unwrap();
        let (a, b) = p.split(0.2, 3).unwrap();
        let (a2, b2) = p.split(0.2, 3).unwrap();
        assert_eq!((a.len(), b.len()), (80, 20));
        assert_eq!((&a, &b), (&a2, &b2));
        let mut all: Vec<f64> = a.as_slice().iter().chain(b.as_slice()).copied().collect();
        all.sort_by(f64::total_cmp);
        assert_eq!(all, (0..100).map(f64::from).collect::<Vec<_>>());
    }
}
