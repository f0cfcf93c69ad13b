//! Point clouds for EM: an N×H row-major array of finite numbers, loaded from CSV / text
//! or NumPy `.npy` files, validated row by row, split into training and held-out parts.
//!
//! Text files hold one point per line, numbers separated by commas, semicolons, tabs or
//! spaces; blank lines and lines starting with `#` are skipped, and a first line that is
//! not numeric is taken as a header. `.npy` files hold a 1-D (N points in 1-D) or 2-D
//! (N×H) array of floats or integers, little- or big-endian, C or Fortran order, read and
//! written with `npyz` (which, unlike `ndarray-npy`, brings no second array stack into a
//! crate built on nalgebra).
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

    /// The points that are not isolated, and how many were left out: a point is an outlier
    /// when its distance to its `k`-th nearest neighbour (among a fixed, evenly spaced
    /// subset of at most 4096 reference points, so the cost stays `O(N·4096)`) is more than
    /// `z` robust standard deviations (and three times) above the median, on a log scale — a
    /// stray point far
    /// from an attractor sampled densely, not the attractor's own sparse parts (at most
    /// `max_share` of the points go, the most isolated first). Deterministic.
    pub fn without_outliers(&self, k: usize, z: f64, max_share: f64) -> (PointSet, usize) {
        let n = self.len();
        if k == 0 || n <= 2 * k + 2 {
            return (self.clone(), 0);
        }
        let reference: Vec<usize> = if n <= 4096 {
            (0..n).collect()
        } else {
            (0..4096).map(|i| i * n / 4096).collect()
        };
        let h = self.dim();
        let logd: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                let p = self.point(i);
                // The k + 1 nearest references, the point itself among them when it is one.
                let mut best = vec![f64::INFINITY; k + 1];
                for &j in &reference {
                    if j == i {
                        continue;
                    }
                    let q = self.point(j);
                    let d2: f64 = (0..h).map(|c| (p[c] - q[c]) * (p[c] - q[c])).sum();
                    if d2 < best[k] {
                        best[k] = d2;
                        best.sort_by(f64::total_cmp);
                    }
                }
                0.5 * best[k - 1].max(1e-300).ln()
            })
            .collect();
        let mut sorted = logd.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[n / 2];
        let mut dev: Vec<f64> = logd.iter().map(|v| (v - median).abs()).collect();
        dev.sort_by(f64::total_cmp);
        let mad = 1.4826 * dev[n / 2];
        if !mad.is_finite() {
            return (self.clone(), 0);
        }
        // At least three times the median distance: evenly spread points are all kept.
        let limit = median + (z * mad).max(3f64.ln());
        let mut order: Vec<usize> = (0..n).filter(|&i| logd[i] > limit).collect();
        order.sort_by(|&a, &b| logd[b].total_cmp(&logd[a]).then(a.cmp(&b)));
        order.truncate((max_share * n as f64).floor() as usize);
        if order.is_empty() {
            return (self.clone(), 0);
        }
        let mut drop = vec![false; n];
        for &i in &order {
            drop[i] = true;
        }
        let kept: Vec<usize> = (0..n).filter(|&i| !drop[i]).collect();
        (self.select(&kept), order.len())
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

    /// The points as a little-endian `float64` `.npy` file of shape (N, H).
    pub fn to_npy(&self) -> Vec<u8> {
        use npyz::WriterBuilder;
        let mut out = Vec::with_capacity(128 + self.data.len() * 8);
        let shape = [self.len() as u64, self.dim as u64];
        // Writing f64s into memory cannot fail.
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&shape)
            .writer(&mut out)
            .begin_nd()
            .expect("writing a .npy header into memory");
        w.extend(self.data.iter().copied())
            .expect("writing .npy data into memory");
        w.finish().expect("writing .npy data into memory");
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

/// The deepest bracket nesting a `.npy` header may have.
const MAX_NPY_HEADER_DEPTH: usize = 8;

/// The header text of a `.npy` buffer that starts with the magic bytes: its length is a
/// little-endian u16 after the version bytes in format 1, a u32 in formats 2 and 3.
fn npy_header(bytes: &[u8]) -> std::result::Result<&[u8], String> {
    let short = || "the .npy header is cut short".to_string();
    let (len, start) = match bytes.get(6) {
        Some(1) => {
            let b = bytes.get(8..10).ok_or_else(short)?;
            (u16::from_le_bytes([b[0], b[1]]) as usize, 10usize)
        }
        Some(2 | 3) => {
            let b = bytes.get(8..12).ok_or_else(short)?;
            (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
        }
        Some(v) => return Err(format!("unknown .npy format version {v}")),
        None => return Err(short()),
    };
    bytes
        .get(start..start.saturating_add(len))
        .ok_or_else(short)
}

/// Refuses a header whose `shape` asks for more values than the file has bytes (or more
/// than a `u64` counts) before the header parser multiplies them out: its product
/// overflowed inside `npyz` and panicked (a fuzz finding). A header without a readable
/// `shape` is left to `npyz`'s own error.
fn npy_shape_fits(header: &[u8], file_len: usize) -> std::result::Result<(), String> {
    let text = String::from_utf8_lossy(header);
    let Some(at) = text.find("'shape'").or_else(|| text.find("\"shape\"")) else {
        return Ok(());
    };
    let rest = &text[at..];
    let (Some(open), Some(close)) = (rest.find('('), rest.find(')')) else {
        return Ok(());
    };
    if close < open {
        return Ok(());
    }
    let mut values: u64 = 1;
    for entry in rest[open + 1..close].split(',') {
        let entry = entry.trim();
        if entry.is_empty() {
            continue;
        }
        let n: u64 = entry.parse().map_err(|_| {
            format!("the .npy header's shape entry `{entry}` is not a whole number a file can hold")
        })?;
        values = values.saturating_mul(n);
    }
    if values > file_len as u64 {
        return Err(format!(
            "data is truncated: the .npy header's shape ({}) asks for {values} values, more than the file's {file_len} bytes hold",
            rest[open + 1..close].trim()
        ));
    }
    Ok(())
}

/// Parses a `.npy` buffer (any format version `npyz` reads); `origin` names the file in errors.
pub fn parse_npy(bytes: &[u8], origin: &Path) -> Result<PointSet> {
    use npyz::{DType, Order, TypeChar};
    let bad = |m: String| Error::file(origin, m);
    if !bytes.starts_with(NPY_MAGIC) {
        return Err(bad(
            "not a NumPy .npy file (missing the \\x93NUMPY magic bytes)".into(),
        ));
    }
    // A header nested deeper than any array's (a plain array's is a flat dict holding one
    // tuple; a structured dtype adds a list of tuples) is refused before the header parser
    // sees it: brackets nested a hundred deep took it minutes (a fuzz finding).
    let header = npy_header(bytes).map_err(&bad)?;
    let mut depth = 0usize;
    for &c in header {
        match c {
            b'{' | b'(' | b'[' => {
                depth += 1;
                if depth > MAX_NPY_HEADER_DEPTH {
                    return Err(bad(format!(
                        "the .npy header nests brackets more than {MAX_NPY_HEADER_DEPTH} deep; \
                         it is not a header NumPy writes"
                    )));
                }
            }
            b'}' | b')' | b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    npy_shape_fits(header, bytes.len()).map_err(&bad)?;
    let file =
        npyz::NpyFile::new(bytes).map_err(|e| bad(format!("cannot read the .npy header: {e}")))?;
    let shape: Vec<usize> = file.shape().iter().map(|&d| d as usize).collect();
    let (n, h) = match shape.as_slice() {
        [n] => (*n, 1),
        [n, h] => (*n, *h),
        other => {
            return Err(bad(format!(
                "array has shape {other:?}; a point cloud must be 1-D (N) or 2-D (N×H)"
            )));
        }
    };
    if n == 0 || h == 0 {
        return Err(bad(format!("array is empty (shape {shape:?})")));
    }
    let fortran = file.order() == Order::Fortran;
    let unsupported = |t: &dyn std::fmt::Display| {
        bad(format!(
            "element type `{t}` is not supported; save the array as float64 (`arr.astype('f8')`)"
        ))
    };
    let ts = match file.dtype() {
        DType::Plain(ts) => ts,
        other => return Err(unsupported(&other.descr())),
    };
    let truncated = |e: std::io::Error| {
        bad(format!(
            "data is truncated or unreadable ({e}); the shape needs {} values",
            n * h
        ))
    };
    macro_rules! read_as {
        ($t:ty) => {
            file.into_vec::<$t>()
                .map_err(truncated)?
                .into_iter()
                .map(|v| v as f64)
                .collect::<Vec<f64>>()
        };
    }
    let flat: Vec<f64> = match (ts.type_char(), ts.size_field()) {
        (TypeChar::Float, 8) => read_as!(f64),
        (TypeChar::Float, 4) => read_as!(f32),
        (TypeChar::Int, 8) => read_as!(i64),
        (TypeChar::Int, 4) => read_as!(i32),
        (TypeChar::Int, 2) => read_as!(i16),
        (TypeChar::Int, 1) => read_as!(i8),
        (TypeChar::Uint, 8) => read_as!(u64),
        (TypeChar::Uint, 4) => read_as!(u32),
        (TypeChar::Uint, 2) => read_as!(u16),
        (TypeChar::Uint, 1) => read_as!(u8),
        (TypeChar::Bool, 1) => file
            .into_vec::<bool>()
            .map_err(truncated)?
            .into_iter()
            .map(f64::from)
            .collect(),
        _ => return Err(unsupported(&ts)),
    };
    if flat.len() < n * h {
        return Err(bad(format!(
            "data is truncated: the shape needs {} values, the file has {}",
            n * h,
            flat.len()
        )));
    }
    let data: Vec<f64> = if fortran {
        // Fortran order: element (i, j) at j·n + i.
        (0..n * h).map(|e| flat[(e % h) * n + e / h]).collect()
    } else {
        flat
    };
    if let Some(pos) = data.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!(
            "row {} has a non-finite coordinate ({}); remove or repair rows with NaN or infinite values",
            pos / h,
            data[pos]
        )));
    }
    PointSet::new(h, data).map_err(|e| Error::file(origin, e))
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
    fn a_shape_larger_than_the_file_is_refused_not_multiplied_out() {
        let npy = |shape: &str| {
            let mut header =
                format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
            while (10 + header.len() + 1) % 64 != 0 {
                header.push(' ');
            }
            header.push('\n');
            let mut b = b"\x93NUMPY\x01\x00".to_vec();
            b.extend_from_slice(&(header.len() as u16).to_le_bytes());
            b.extend_from_slice(header.as_bytes());
            b.extend_from_slice(&[0u8; 48]);
            b
        };
        for shape in [
            "(4294967296, 4294967296)",
            "(18446744073709551615, 3)",
            "(99999999999999999999999,)",
            "(1000, 2)",
        ] {
            let err = parse_npy(&npy(shape), Path::new("big.npy"))
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("big.npy") && err.contains("shape"),
                "{shape}: {err}"
            );
        }
        // A shape the data holds still reads.
        let ok = parse_npy(&npy("(3, 2)"), Path::new("ok.npy")).unwrap();
        assert_eq!(ok.len(), 3);
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
        // Big-endian float32, C order, version 2.0 header.
        let dict = "{'descr': '>f4', 'fortran_order': False, 'shape': (3, 1), }";
        let mut b = NPY_MAGIC.to_vec();
        b.extend_from_slice(&[2, 0]);
        b.extend_from_slice(&(dict.len() as u32).to_le_bytes());
        b.extend_from_slice(dict.as_bytes());
        for v in [0.5f32, -1.25, 3.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        let g = parse_npy(&b, Path::new("g.npy")).unwrap();
        assert_eq!((g.dim(), g.as_slice()), (1, &[0.5, -1.25, 3.0][..]));
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

    #[test]
    fn isolated_points_are_left_out_and_a_clean_cloud_is_kept_whole() {
        // 2000 points on a circle (dense), 20 scattered far from it (1 %).
        let mut data = Vec::new();
        for i in 0..2000 {
            let a = std::f64::consts::TAU * i as f64 / 2000.0;
            data.extend_from_slice(&[a.cos(), a.sin()]);
        }
        let clean = PointSet::new(2, data.clone()).unwrap();
        let (kept, removed) = clean.without_outliers(8, 4.0, 0.05);
        assert_eq!((kept.len(), removed), (2000, 0));
        for j in 0..20 {
            let a = 2.399 * j as f64;
            data.extend_from_slice(&[3.0 * a.cos() + 0.1 * j as f64, 3.0 * a.sin()]);
        }
        let noisy = PointSet::new(2, data).unwrap();
        let (kept, removed) = noisy.without_outliers(8, 4.0, 0.05);
        assert_eq!(removed, 20);
        assert!(kept.iter().all(|p| (p[0].hypot(p[1]) - 1.0).abs() < 1e-9));
        // Never more than the share allowed.
        assert!(noisy.without_outliers(8, 4.0, 0.005).1 <= 10);
    }
}
