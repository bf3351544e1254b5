//! Symmetries measured on the mesh itself.
//!
//! The catalogue declares a *kind* of symmetry per object (`discrete`: a box-like object with 180°
//! flips; `continuous_z`: a body of revolution about the model z axis). The model frame keeps the
//! axes of the scan, and real scans are not aligned with their faces (the YCB gelatin box is turned
//! about 13° about z), so the axis-aligned transforms the kind names can move the surface by
//! centimetres. This module
//!
//! - **measures** how far a rigid transform moves a mesh's surface off itself: area-weighted,
//!   seeded surface samples are moved by the transform, and each one's exact distance to the closest
//!   point of the surface (point-to-triangle, through a bounding-volume hierarchy) is taken;
//!   [`Displacement`] reports the maximum and the 99th and 95th percentiles;
//! - **derives** the symmetries of a declared kind from the mesh: the box frame (principal axes of
//!   the area-weighted surface covariance, centred on the bounding box in that frame, and the model
//!   axes as a second start) refined by a small pattern search, its three 180° flips for `discrete`;
//!   the revolution axis (the principal axis nearest model z) refined the same way and verified at
//!   every 30° for `continuous_z`; a symmetry is kept only when it passes [`tolerance`].
//!
//! Everything is deterministic (a fixed seed, no threads, only `+ − × ÷ √` in the search), so the
//! same mesh gives the same bytes in `models_info.json` on every run. Nothing is logged: the result
//! carries every measurement ([`DerivedSymmetries::checks`]) for the caller to report.

use glam::{DMat3, DMat4, DQuat, DVec3};

use crate::catalog::Symmetry;
use crate::mesh::diameter_of;

/// Surface samples used to measure a transform ("a few thousand", area-weighted).
pub const SURFACE_SAMPLES: usize = 4000;
/// Seed of the surface samples (SplitMix64).
pub const SAMPLE_SEED: u64 = 0x7667_656e_5f73_796d;
/// The samples the refinement search uses (a prefix of the random samples, so a random subset).
const SEARCH_SAMPLES: usize = 1000;

/// The tolerance of a symmetry: max(1 mm, 1% of the diameter). A transform is a symmetry when it
/// moves 95% of the surface by at most the tolerance and 99% by at most twice it
/// ([`Displacement::passes`]).
///
/// Why the 95th percentile, and not the maximum or the 99th alone: the real scans are not exact
/// boxes or cylinders, and their worst points are where the physical object is bent, not where the
/// shape has another symmetry. Measured on the 11 google_16k scans (4000 samples, the frame the
/// search finds; p95 / p99 / max in mm, the tolerance in brackets):
///
/// | scan | transform | p95 | p99 | max | |
/// |---|---|---|---|---|---|
/// | gelatin box [1.14] | flips x, y, z | 0.89–0.94 | 1.37–1.47 | 1.79–2.02 | kept: its lid bulges ~1.5 mm |
/// | sugar box [1.99] | flip z | 1.11 | 1.52 | 2.35 | kept |
/// | sugar box | flips x, y | 3.15, 3.28 | 3.53, 3.92 | 3.70, 4.15 | dropped: 45 mm thick at the base, 39 mm at the top |
/// | potted meat can [1.29] | flip z | 0.41 | 1.47 | 2.64 | kept |
/// | potted meat can | flips x, y (lid ↔ base) | 2.61, 2.62 | 4.18, 4.14 | 5.71, 5.77 | dropped |
/// | cracker box [2.70] | flips x, y, z | 4.01–5.20 | 5.09–6.19 | 5.48–6.63 | dropped: a 6–7 mm dent in a large face |
/// | tomato soup can [1.21] | turns by 30°…330° (worst) | 2.50 | 3.82 | 4.80 | dropped: the wall is out of round by up to 2.8 mm (circle fits per height: centres within 0.2 mm of the axis, residual RMS 0.3–0.9 mm) |
///
/// Under the maximum, or the 99th percentile alone, the gelatin box would lose all three flips to
/// the 1.5 mm bulge of its lid, although they are 12 times better than the axis-aligned flips (p95
/// 11 mm, p99 14 mm). The 95th percentile alone would let a twentieth of the surface move
/// arbitrarily far: the procedural mug's best flip about its body axis has p95 0.02 mm and p99
/// 22 mm (the handle), and is caught only by the 99th percentile at twice the tolerance. The
/// procedural stand-ins' symmetries are exact (< 0.001 mm), and every wrong transform measured fails
/// by far: the axis-aligned flips of a box turned 13° (p95 12.8 mm), a quarter turn of a 60 × 100 mm
/// box, a box or a mug as a body of revolution.
pub fn tolerance(diameter: f64) -> f64 {
    (0.01 * diameter).max(0.001)
}

/// How far a transform moves the surface off itself, metres: statistics over the surface samples of
/// the distance from the moved sample to the closest point of the (unmoved) surface.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Displacement {
    pub max: f64,
    pub p99: f64,
    pub p95: f64,
}

impl Displacement {
    /// Whether the transform is a symmetry within `tolerance`: p95 ≤ tolerance and p99 ≤ 2 ×
    /// tolerance (see [`tolerance`]).
    pub fn passes(&self, tolerance: f64) -> bool {
        self.p95 <= tolerance && self.p99 <= 2.0 * tolerance
    }

    /// The worse of two, statistic by statistic (for a family of transforms).
    pub fn worst(self, other: Displacement) -> Displacement {
        Displacement { max: self.max.max(other.max), p99: self.p99.max(other.p99), p95: self.p95.max(other.p95) }
    }

    fn from_distances(mut d: Vec<f64>) -> Displacement {
        if d.is_empty() {
            return Displacement::default();
        }
        d.sort_by(f64::total_cmp);
        // Nearest-rank percentiles.
        let rank = |q: f64| d[((q * d.len() as f64).ceil() as usize).clamp(1, d.len()) - 1];
        Displacement { max: d[d.len() - 1], p99: rank(0.99), p95: rank(0.95) }
    }
}

/// A continuous symmetry: revolution about the line through `offset` along `axis` (unit), model
/// frame, metres (BOP's `symmetries_continuous` entry, in metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuousAxis {
    pub axis: DVec3,
    pub offset: DVec3,
}

/// One symmetry that was checked: the catalogue's fixed transform and the derived one.
#[derive(Debug, Clone, PartialEq)]
pub struct SymmetryCheck {
    /// `flip x`, `flip y`, `flip z` (a 180° turn about the box axis nearest that model axis) or
    /// `revolution z` (every 30° about the axis nearest model z; the worst turn is reported).
    pub name: &'static str,
    /// What the catalogue's axis-aligned transform (through the model origin) does to this mesh.
    pub declared: Displacement,
    /// What the derived transform does.
    pub derived: Displacement,
    /// The derived transform passed the tolerance and is in [`DerivedSymmetries`].
    pub kept: bool,
}

/// The symmetries of a mesh for a declared kind, verified on the mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedSymmetries {
    /// The kind the catalogue (or config) declares.
    pub declared: Symmetry,
    /// The kind that survived: `declared`, or [`Symmetry::None`] when no symmetry passed.
    pub kind: Symmetry,
    /// The kept 180° flips, model frame (rotation and translation in metres).
    pub discrete: Vec<DMat4>,
    /// The kept revolution axis.
    pub continuous: Vec<ContinuousAxis>,
    /// The tolerance applied (metres): max(1 mm, 1% of `diameter`), see [`tolerance`].
    pub tolerance: f64,
    /// Largest distance between two vertices, metres.
    pub diameter: f64,
    /// Every checked candidate, kept or dropped, with its measurements.
    pub checks: Vec<SymmetryCheck>,
}

impl DerivedSymmetries {
    /// The kept flips as BOP-style row-major 4×4 matrices (translation in metres).
    pub fn discrete_row_major(&self) -> Vec<[f64; 16]> {
        self.discrete.iter().map(row_major4).collect()
    }

    /// The checks whose symmetry did not survive.
    pub fn dropped(&self) -> impl Iterator<Item = &SymmetryCheck> {
        self.checks.iter().filter(|c| !c.kept)
    }
}

/// A 4×4 matrix as 16 row-major values.
pub fn row_major4(m: &DMat4) -> [f64; 16] {
    m.transpose().to_cols_array()
}

/// The transforms the catalogue's kind stood for before symmetries were measured: the three 180°
/// flips about the model x, y, z axes through the origin (`discrete`), or turns about the model z
/// axis through the origin (`continuous_z`, here every 30°).
pub fn axis_aligned_transforms(kind: Symmetry) -> Vec<DMat4> {
    let frame = Frame { r: DQuat::IDENTITY, c: DVec3::ZERO };
    match kind {
        Symmetry::None => Vec::new(),
        Symmetry::Discrete => FLIPS.iter().map(|f| frame.model_transform(f)).collect(),
        Symmetry::ContinuousZ => (1..12).map(|k| frame.model_transform(&turn_z_30(k))).collect(),
    }
}

/// The turns by 30°, 60°, …, 330° about a revolution axis, model frame: how a continuous symmetry is
/// verified.
pub fn revolution_turns(a: &ContinuousAxis) -> Vec<DMat4> {
    let frame = Frame { r: DQuat::from_rotation_arc(DVec3::Z, a.axis.normalize()), c: a.offset };
    (1..12).map(|k| frame.model_transform(&turn_z_30(k))).collect()
}

/// Derives the symmetries of kind `declared` from a triangle mesh (model frame, metres; `indices`
/// three per triangle) and keeps those that move the surface by at most the tolerance.
pub fn derive_symmetries(positions: &[[f32; 3]], indices: &[u32], declared: Symmetry) -> DerivedSymmetries {
    let checker = SymmetryChecker::new(positions, indices);
    checker.derive(declared)
}

/// Measures transforms of one mesh: its surface samples and exact closest-point distances.
pub struct SymmetryChecker {
    surface: Bvh,
    samples: Vec<DVec3>,
    diameter: f64,
    /// Area-weighted centroid and covariance of the surface.
    centroid: DVec3,
    covariance: DMat3,
    vertices: Vec<DVec3>,
}

impl SymmetryChecker {
    /// [`SURFACE_SAMPLES`] samples with [`SAMPLE_SEED`].
    pub fn new(positions: &[[f32; 3]], indices: &[u32]) -> Self {
        Self::with_samples(positions, indices, SURFACE_SAMPLES, SAMPLE_SEED)
    }

    pub fn with_samples(positions: &[[f32; 3]], indices: &[u32], samples: usize, seed: u64) -> Self {
        let vertices: Vec<DVec3> = positions.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
        let tris: Vec<[DVec3; 3]> = indices
            .chunks_exact(3)
            .filter_map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| vertices.get(i as usize).copied());
                Some([a?, b?, c?])
            })
            // Zero-area triangles add no surface (their points lie on their neighbours' edges).
            .filter(|[a, b, c]| (*b - *a).cross(*c - *a).length_squared() > 0.0)
            .collect();
        // Area, centroid and second moment (exact over each triangle).
        let mut area = 0.0;
        let mut first = DVec3::ZERO;
        let mut second = DMat3::ZERO;
        let mut cumulative = Vec::with_capacity(tris.len());
        for [a, b, c] in &tris {
            let ar = 0.5 * (*b - *a).cross(*c - *a).length();
            let s = *a + *b + *c;
            area += ar;
            first += ar / 3.0 * s;
            second += (outer(*a, *a) + outer(*b, *b) + outer(*c, *c) + outer(s, s)) * (ar / 12.0);
            cumulative.push(area);
        }
        let (centroid, covariance) = if area > 0.0 {
            let c = first / area;
            (c, second * (1.0 / area) - outer(c, c))
        } else {
            (DVec3::ZERO, DMat3::ZERO)
        };
        // Area-weighted samples: a triangle by its cumulative area, a point uniformly in it.
        let mut rng = SplitMix64(seed);
        let mut pts = Vec::with_capacity(samples);
        if area > 0.0 {
            for _ in 0..samples {
                let u = rng.next_f64() * area;
                let k = cumulative.partition_point(|&c| c <= u).min(tris.len() - 1);
                let [a, b, c] = tris[k];
                let (r1, r2) = (rng.next_f64(), rng.next_f64());
                let s = r1.sqrt();
                pts.push(a * (1.0 - s) + b * (s * (1.0 - r2)) + c * (s * r2));
            }
        }
        SymmetryChecker { surface: Bvh::new(tris), samples: pts, diameter: diameter_of(positions), centroid, covariance, vertices }
    }

    pub fn diameter(&self) -> f64 {
        self.diameter
    }

    /// max(1 mm, 1% of the diameter).
    pub fn tolerance(&self) -> f64 {
        tolerance(self.diameter)
    }

    /// The surface samples (model frame, metres).
    pub fn samples(&self) -> &[DVec3] {
        &self.samples
    }

    /// Exact distance from `p` to the closest point of the mesh surface.
    pub fn distance(&self, p: DVec3) -> f64 {
        self.surface.distance_sq(p, &mut Vec::new()).sqrt()
    }

    /// How far `t` (a rigid transform in the model frame) moves the surface off itself.
    pub fn displacement(&self, t: &DMat4) -> Displacement {
        let mut stack = Vec::with_capacity(64);
        Displacement::from_distances(
            self.samples.iter().map(|p| self.surface.distance_sq(t.transform_point3(*p), &mut stack).sqrt()).collect(),
        )
    }

    /// The worst displacement over a family of transforms.
    pub fn worst_displacement(&self, ts: &[DMat4]) -> Displacement {
        ts.iter().map(|t| self.displacement(t)).fold(Displacement::default(), Displacement::worst)
    }

    /// Derives and verifies the symmetries of kind `declared` (see [`derive_symmetries`]).
    pub fn derive(&self, declared: Symmetry) -> DerivedSymmetries {
        let tol = self.tolerance();
        let mut out = DerivedSymmetries {
            declared,
            kind: Symmetry::None,
            discrete: Vec::new(),
            continuous: Vec::new(),
            tolerance: tol,
            diameter: self.diameter,
            checks: Vec::new(),
        };
        if self.samples.is_empty() {
            return out;
        }
        match declared {
            Symmetry::None => {}
            Symmetry::Discrete => {
                let frame = self.best_frame(&self.principal_frame(false), &FLIPS);
                let axis_aligned = axis_aligned_transforms(Symmetry::Discrete);
                for ((flip, old), name) in FLIPS.iter().zip(&axis_aligned).zip(["flip x", "flip y", "flip z"]) {
                    let t = round_transform(&frame.model_transform(flip));
                    let derived = self.displacement(&t);
                    let kept = derived.passes(tol);
                    if kept {
                        out.discrete.push(t);
                    }
                    out.checks.push(SymmetryCheck { name, declared: self.displacement(old), derived, kept });
                }
            }
            Symmetry::ContinuousZ => {
                let search = [turn_z_30(2), turn_z_30(3), turn_z_30(6)];
                let frame = self.best_frame(&self.principal_frame(true), &search);
                let mut axis = DMat3::from_quat(frame.r) * DVec3::Z;
                if axis.z < 0.0 {
                    axis = -axis;
                }
                // The point of the axis nearest the model origin.
                let found = ContinuousAxis { axis: round_vec(axis), offset: round_vec(frame.c - axis * axis.dot(frame.c)) };
                let derived = self.worst_displacement(&revolution_turns(&found));
                let declared = self.worst_displacement(&axis_aligned_transforms(Symmetry::ContinuousZ));
                let kept = derived.passes(tol);
                if kept {
                    out.continuous.push(found);
                }
                out.checks.push(SymmetryCheck { name: "revolution z", declared, derived, kept });
            }
        }
        if !out.discrete.is_empty() || !out.continuous.is_empty() {
            out.kind = declared;
        }
        out
    }

    /// The frame of the principal axes of the surface covariance, centred on the bounding box of
    /// the vertices in that frame (a box scan's centroid is pulled towards its better-scanned
    /// faces; the box's centre is not). Its local axes are the principal axes nearest the model x,
    /// y, z axes (`axis_nearest_z`: only local z is matched, to the axis nearest model z).
    fn principal_frame(&self, axis_nearest_z: bool) -> Frame {
        let (_, vecs) = symmetric_eigen(self.covariance);
        // Assign principal axes to model axes: the permutation with the largest total |cos|.
        const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
        let score = |p: &[usize; 3]| {
            if axis_nearest_z { vecs[p[2]].z.abs() } else { (0..3).map(|k| vecs[p[k]][k].abs()).sum::<f64>() }
        };
        let best = PERMS.iter().copied().fold(PERMS[0], |b, p| if score(&p) > score(&b) { p } else { b });
        let mut x = vecs[best[0]];
        let mut z = vecs[best[2]];
        if x.x < 0.0 {
            x = -x;
        }
        if z.z < 0.0 {
            z = -z;
        }
        let y = z.cross(x);
        let r = DQuat::from_mat3(&DMat3::from_cols(x, y, z)).normalize();
        let rm = DMat3::from_cols(x, y, z);
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for v in &self.vertices {
            let l = rm.transpose() * (*v - self.centroid);
            lo = lo.min(l);
            hi = hi.max(l);
        }
        Frame { r, c: self.centroid + rm * ((lo + hi) * 0.5) }
    }

    /// Refines the principal frame and the model frame (the two starts) against the local
    /// transforms `ops` and returns the better one.
    fn best_frame(&self, principal: &Frame, ops: &[DMat3]) -> Frame {
        let starts = [*principal, Frame { r: DQuat::IDENTITY, c: DVec3::ZERO }];
        let mut best: Option<(f64, Frame)> = None;
        for s in starts {
            let (f, cost) = self.refine(s, ops);
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, f));
            }
        }
        best.expect("two starts").1
    }

    /// The search objective at `frame`: over `ops`, the mean displacement of the search samples,
    /// each capped at 3 tolerances (a transform that does not hold then weighs little and cannot
    /// drag the frame away from the ones that do); and the Gauss–Newton normal equations of the
    /// point-to-plane residuals of the samples within the cap, for the frame's 6 parameters (a turn
    /// about its own axes, a move along the model axes).
    fn evaluate(&self, frame: &Frame, ops: &[DMat3], stack: &mut Vec<usize>) -> (f64, [[f64; 6]; 6], [f64; 6]) {
        let cap = 3.0 * self.tolerance();
        let n = self.samples.len().min(SEARCH_SAMPLES);
        let (mut sum, mut jtj, mut jtr) = (0.0, [[0.0; 6]; 6], [0.0; 6]);
        const H: f64 = 1e-7;
        for op in ops {
            let t = frame.model_transform(op);
            // d(T p)/d(parameter k) = D_k p: T is affine in p, so one difference per parameter.
            let d: [DMat4; 6] = std::array::from_fn(|k| (frame.step(k, H).model_transform(op) - t) * (1.0 / H));
            for p in &self.samples[..n] {
                let y = t.transform_point3(*p);
                match self.surface.closest(y, cap * cap, stack) {
                    Some((dist_sq, q, normal)) => {
                        sum += dist_sq.sqrt();
                        let r = normal.dot(y - q);
                        let j: [f64; 6] = std::array::from_fn(|k| normal.dot(d[k].transform_vector3(*p) + d[k].w_axis.truncate()));
                        for a in 0..6 {
                            jtr[a] += j[a] * r;
                            for b in 0..6 {
                                jtj[a][b] += j[a] * j[b];
                            }
                        }
                    }
                    None => sum += cap,
                }
            }
        }
        (sum / (n * ops.len()) as f64, jtj, jtr)
    }

    /// Levenberg–Marquardt on the point-to-plane residuals from `start` (an ICP whose moved copy is
    /// the surface under `ops`), each step kept only when the capped mean displacement drops; stops
    /// when it drops by less than 1 nm or no step helps. Returns the frame and that mean.
    fn refine(&self, start: Frame, ops: &[DMat3]) -> (Frame, f64) {
        let mut stack = Vec::with_capacity(64);
        let mut frame = start;
        let (mut cost, mut jtj, mut jtr) = self.evaluate(&frame, ops, &mut stack);
        let mut lambda = 1e-3;
        for _ in 0..60 {
            let mut a = jtj;
            let trace: f64 = (0..6).map(|k| jtj[k][k]).sum();
            for (k, row) in a.iter_mut().enumerate() {
                // Marquardt's scaling, and a floor for the directions no residual sees (a turn
                // about a revolution axis, a move along a flip axis).
                row[k] += lambda * jtj[k][k] + 1e-12 * trace;
            }
            let Some(delta) = solve6(a, jtr.map(|v| -v)) else { break };
            let mut cand = frame;
            for (k, dk) in delta.iter().enumerate() {
                cand = cand.step(k, *dk);
            }
            let (c, j2, r2) = self.evaluate(&cand, ops, &mut stack);
            if c < cost {
                let gain = cost - c;
                (frame, cost, jtj, jtr) = (cand, c, j2, r2);
                lambda = (lambda / 3.0).max(1e-9);
                if gain < 1e-9 {
                    break;
                }
            } else {
                lambda *= 4.0;
                if lambda > 1e6 {
                    break;
                }
            }
        }
        (frame, cost)
    }
}

/// Solves the 6×6 system `a x = b` (Gaussian elimination, partial pivoting); `None` when singular.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let piv = (col..6).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 || !a[piv][col].is_finite() {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..6 {
            let f = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (x, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 6];
    for row in (0..6).rev() {
        let s: f64 = (row + 1..6).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The three 180° flips about the local x, y, z axes.
const FLIPS: [DMat3; 3] = [
    DMat3::from_cols(DVec3::X, DVec3::NEG_Y, DVec3::NEG_Z),
    DMat3::from_cols(DVec3::NEG_X, DVec3::Y, DVec3::NEG_Z),
    DMat3::from_cols(DVec3::NEG_X, DVec3::NEG_Y, DVec3::Z),
];

/// A turn by `k`·30° about the local z axis (exact sines: no libm, same bits everywhere).
fn turn_z_30(k: u32) -> DMat3 {
    let h = 0.75f64.sqrt();
    // k·30° = q·90° + r·30°.
    let (c0, s0) = [(1.0, 0.0), (h, 0.5), (0.5, h)][(k % 3) as usize];
    let (c, s) = match (k / 3) % 4 {
        0 => (c0, s0),
        1 => (-s0, c0),
        2 => (-c0, -s0),
        _ => (s0, -c0),
    };
    DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z)
}

/// The rotation by the small rotation vector `v` (Cayley-like: only `√`, no libm trigonometry).
fn small_rotation(v: DVec3) -> DQuat {
    DQuat::from_xyzw(0.5 * v.x, 0.5 * v.y, 0.5 * v.z, 1.0).normalize()
}

/// A symmetry group's frame: `r` turns local axes into model axes, `c` is the local origin.
#[derive(Debug, Clone, Copy)]
struct Frame {
    r: DQuat,
    c: DVec3,
}

impl Frame {
    /// The frame moved by `amount` along parameter `k`: 0–2 turn it about its own x, y, z axes
    /// (radians), 3–5 move its origin along the model x, y, z axes (metres).
    fn step(&self, k: usize, amount: f64) -> Frame {
        let mut v = DVec3::ZERO;
        v[k % 3] = amount;
        if k < 3 { Frame { r: (self.r * small_rotation(v)).normalize(), c: self.c } } else { Frame { r: self.r, c: self.c + v } }
    }

    /// The local linear map `op` (about the frame's origin) as a model-frame transform.
    fn model_transform(&self, op: &DMat3) -> DMat4 {
        let r = DMat3::from_quat(self.r);
        let m = r * *op * r.transpose();
        let t = self.c - m * self.c;
        DMat4::from_cols(m.x_axis.extend(0.0), m.y_axis.extend(0.0), m.z_axis.extend(0.0), t.extend(1.0))
    }
}

/// Rounds to 1e-9 (nanometres for translations): the written values do not carry the search's
/// last bits.
fn round9(x: f64) -> f64 {
    let r = (x * 1e9).round() / 1e9;
    if r == 0.0 { 0.0 } else { r }
}

fn round_vec(v: DVec3) -> DVec3 {
    DVec3::new(round9(v.x), round9(v.y), round9(v.z))
}

fn round_transform(m: &DMat4) -> DMat4 {
    DMat4::from_cols_array(&m.to_cols_array().map(round9))
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Eigen-decomposition of a symmetric 3×3 matrix (cyclic Jacobi): eigenvalues and unit
/// eigenvectors, in no particular order.
fn symmetric_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m.to_cols_array_2d(); // a[col][row]; symmetric, so a[i][j] = a[j][i]
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]; // v[col][row]: columns are eigenvectors
    for _ in 0..64 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let scale = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= 1e-30 * scale.max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A <- Jᵀ A J with the rotation J in the (p, q) plane.
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            let (row_p, row_q) = (v[p], v[q]);
            for k in 0..3 {
                v[p][k] = c * row_p[k] - s * row_q[k];
                v[q][k] = s * row_p[k] + c * row_q[k];
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], [DVec3::from(v[0]), DVec3::from(v[1]), DVec3::from(v[2])])
}

/// SplitMix64: a small, fixed, platform-independent random stream.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// A bounding-volume hierarchy over triangles for exact closest-point distances.
struct Bvh {
    tris: Vec<[DVec3; 3]>,
    /// Unit normals of `tris`.
    normals: Vec<DVec3>,
    nodes: Vec<BvhNode>,
}

struct BvhNode {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: `tris[start..end]`; inner: children `start` and `end`.
    start: usize,
    end: usize,
    leaf: bool,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    fn new(mut tris: Vec<[DVec3; 3]>) -> Self {
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 2);
        if !tris.is_empty() {
            let n = tris.len();
            Self::build(&mut nodes, &mut tris, 0, n);
        }
        let normals = tris.iter().map(|[a, b, c]| (*b - *a).cross(*c - *a).normalize()).collect();
        Bvh { tris, normals, nodes }
    }

    /// Builds the node over `tris[start..end]` (median split along the widest centroid extent);
    /// returns its index.
    fn build(nodes: &mut Vec<BvhNode>, tris: &mut [[DVec3; 3]], start: usize, end: usize) -> usize {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut clo, mut chi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in &tris[start..end] {
            for p in t {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let c = (t[0] + t[1] + t[2]) / 3.0;
            clo = clo.min(c);
            chi = chi.max(c);
        }
        let index = nodes.len();
        nodes.push(BvhNode { lo, hi, start, end, leaf: true });
        if end - start > LEAF_SIZE {
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (start + end) / 2;
            let key = |t: &[DVec3; 3]| t[0][axis] + t[1][axis] + t[2][axis];
            tris[start..end].select_nth_unstable_by(mid - start, |a, b| key(a).total_cmp(&key(b)));
            let left = Self::build(nodes, tris, start, mid);
            let right = Self::build(nodes, tris, mid, end);
            nodes[index] = BvhNode { lo, hi, start: left, end: right, leaf: false };
        }
        index
    }

    fn box_distance_sq(n: &BvhNode, p: DVec3) -> f64 {
        let d = (n.lo - p).max(p - n.hi).max(DVec3::ZERO);
        d.length_squared()
    }

    /// Squared distance from `p` to the closest point of the surface.
    fn distance_sq(&self, p: DVec3, stack: &mut Vec<usize>) -> f64 {
        self.closest(p, f64::INFINITY, stack).map_or(f64::INFINITY, |c| c.0)
    }

    /// The closest point of the surface to `p` if it is nearer than √`cap_sq`: squared distance,
    /// point, and the normal of its triangle.
    fn closest(&self, p: DVec3, cap_sq: f64, stack: &mut Vec<usize>) -> Option<(f64, DVec3, DVec3)> {
        let mut best = cap_sq;
        let mut found = None;
        if self.nodes.is_empty() {
            return None;
        }
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            if Self::box_distance_sq(n, p) >= best {
                continue;
            }
            if n.leaf {
                for k in n.start..n.end {
                    let q = closest_point_on_triangle(p, &self.tris[k]);
                    let d = (q - p).length_squared();
                    if d < best {
                        best = d;
                        found = Some((q, k));
                    }
                }
            } else {
                // Nearer child last, so it is searched first.
                let (dl, dr) = (Self::box_distance_sq(&self.nodes[n.start], p), Self::box_distance_sq(&self.nodes[n.end], p));
                if dl < dr {
                    stack.extend([n.end, n.start]);
                } else {
                    stack.extend([n.start, n.end]);
                }
            }
        }
        found.map(|(q, k)| (best, q, self.normals[k]))
    }
}

/// The closest point of triangle `t` to `p` (Ericson, *Real-Time Collision Detection*, 5.1.5).
fn closest_point_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{Catalog, Shape};
    use crate::load::{find_ycb_mesh, load_mesh};
    use crate::mesh::TexturedMesh;
    use crate::procedural::procedural_mesh;

    fn mm(d: &Displacement) -> String {
        format!("{:6.2} {:6.2} {:6.2}", 1e3 * d.max, 1e3 * d.p99, 1e3 * d.p95)
    }

    /// One line per check: the declared (axis-aligned) and derived displacement, mm.
    fn print_table(id: &str, s: &DerivedSymmetries) {
        for c in &s.checks {
            eprintln!(
                "{id:<22} {:<13} {:<12} | declared max/p99/p95 {} | derived {} | tol {:.2} | {}",
                s.declared.as_str(),
                c.name,
                mm(&c.declared),
                mm(&c.derived),
                1e3 * s.tolerance,
                if c.kept { "kept" } else { "DROPPED" }
            );
        }
        if s.checks.is_empty() {
            eprintln!("{id:<22} {:<13} (nothing to check)", s.declared.as_str());
        }
    }

    /// Every derived symmetry, measured again with independent samples (another seed, more of
    /// them), moves the surface by at most the tolerance; returns the worst p99.
    fn assert_derived_hold(id: &str, m: &TexturedMesh, s: &DerivedSymmetries) -> f64 {
        let check = SymmetryChecker::with_samples(&m.positions, &m.indices, 6000, 12345);
        let mut worst: f64 = 0.0;
        for t in &s.discrete {
            let d = check.displacement(t);
            assert!(d.passes(s.tolerance), "{id}: derived flip moves the surface by {} mm (tolerance {:.2})", mm(&d), 1e3 * s.tolerance);
            worst = worst.max(d.p99);
        }
        for a in &s.continuous {
            assert!((a.axis.length() - 1.0).abs() < 1e-6, "{id}: unit axis");
            let d = check.worst_displacement(&revolution_turns(a));
            assert!(d.passes(s.tolerance), "{id}: derived revolution moves the surface by {} mm", mm(&d));
            worst = worst.max(d.p99);
        }
        worst
    }

    fn box_mesh(half: DVec3, turn_z_deg: f64) -> TexturedMesh {
        let mut e = Catalog::builtin().get("009_gelatin_box").unwrap().clone();
        e.shape = Shape::Box;
        e.extents = (half * 2.0).to_array();
        let mut m = procedural_mesh(&e);
        let q = DQuat::from_rotation_z(turn_z_deg.to_radians());
        for p in &mut m.positions {
            *p = (q * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).as_vec3().into();
        }
        m.center_on_aabb();
        m
    }

    #[test]
    fn closest_points_are_exact() {
        let m = procedural_mesh(Catalog::builtin().get("025_mug").unwrap());
        let c = SymmetryChecker::new(&m.positions, &m.indices);
        let tris: Vec<[DVec3; 3]> =
            m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|i| Vec3f(m.positions[i as usize]).d())).collect();
        let mut rng = SplitMix64(3);
        for _ in 0..300 {
            let p = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5) * 0.2;
            let brute = tris.iter().map(|t| (closest_point_on_triangle(p, t) - p).length()).fold(f64::INFINITY, f64::min);
            assert!((c.distance(p) - brute).abs() < 1e-12, "{} vs {brute}", c.distance(p));
        }
        // Samples lie on the surface; the identity moves nothing.
        assert!(c.samples().iter().all(|p| c.distance(*p) < 1e-9));
        assert_eq!(c.displacement(&DMat4::IDENTITY).max, c.samples().iter().map(|p| c.distance(*p)).fold(0.0, f64::max));
        // A point on a face of a triangle, off it along the normal.
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(closest_point_on_triangle(DVec3::new(0.2, 0.2, 1.0), &t).abs_diff_eq(DVec3::new(0.2, 0.2, 0.0), 1e-15));
        assert_eq!(closest_point_on_triangle(DVec3::new(2.0, -1.0, 0.0), &t), DVec3::X);
        assert_eq!(closest_point_on_triangle(DVec3::new(1.0, 1.0, 0.0), &t), DVec3::new(0.5, 0.5, 0.0));
    }

    struct Vec3f([f32; 3]);
    impl Vec3f {
        fn d(&self) -> DVec3 {
            DVec3::new(self.0[0] as f64, self.0[1] as f64, self.0[2] as f64)
        }
    }

    #[test]
    fn eigen_decomposition_of_a_turned_diagonal() {
        let r = DMat3::from_quat(DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1));
        let m = r * DMat3::from_diagonal(DVec3::new(1.0, 4.0, 9.0)) * r.transpose();
        let (vals, vecs) = symmetric_eigen(m);
        let mut seen = [false; 3];
        for (l, v) in vals.iter().zip(vecs) {
            assert!((m * v - v * *l).length() < 1e-12, "{l} {v}");
            assert!((v.length() - 1.0).abs() < 1e-12);
            let k = [1.0, 4.0, 9.0].iter().position(|x| (x - l).abs() < 1e-9).unwrap();
            seen[k] = true;
        }
        assert_eq!(seen, [true; 3]);
    }

    #[test]
    fn turns_by_30_degrees_are_exact_rotations() {
        for k in 0..12 {
            let m = turn_z_30(k);
            let a = (k as f64 * 30.0).to_radians();
            assert!((m.x_axis - DVec3::new(a.cos(), a.sin(), 0.0)).length() < 1e-15, "{k}");
            assert!((m.determinant() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn flips_of_a_box_turned_13_degrees_are_found_and_the_axis_aligned_ones_fail() {
        let m = box_mesh(DVec3::new(0.0447, 0.0505, 0.015), 13.0);
        let s = derive_symmetries(&m.positions, &m.indices, Symmetry::Discrete);
        print_table("box turned 13°", &s);
        assert_eq!(s.kind, Symmetry::Discrete);
        assert_eq!(s.discrete.len(), 3, "all three flips found");
        for c in &s.checks {
            // The flip about z still holds; the x and y flips are caught.
            assert_eq!(c.declared.passes(s.tolerance), c.name == "flip z", "{}: axis-aligned flip {}", c.name, mm(&c.declared));
            assert!(c.derived.p99 < 0.05e-3, "{}: the derived flip is exact: {}", c.name, mm(&c.derived));
        }
        // The flips' axes are the box's: x and y turned by 13° about z.
        let q = DQuat::from_rotation_z(13f64.to_radians());
        for (t, axis) in s.discrete.iter().zip([q * DVec3::X, q * DVec3::Y, DVec3::Z]) {
            let want = DMat3::from_cols(axis * axis.x, axis * axis.y, axis * axis.z) * 2.0 - DMat3::IDENTITY;
            let got = DMat3::from_mat4(*t);
            assert!((got.x_axis - want.x_axis).length() + (got.y_axis - want.y_axis).length() < 1e-4, "{got} vs {want}");
            assert!(t.w_axis.truncate().length() < 1e-5, "through the box centre: {}", t.w_axis);
        }
        assert_derived_hold("box turned 13°", &m, &s);
    }

    #[test]
    fn wrong_symmetries_are_caught() {
        // A quarter turn of a non-square box moves its long faces by the difference of the sides.
        let m = box_mesh(DVec3::new(0.03, 0.05, 0.02), 0.0);
        let c = SymmetryChecker::new(&m.positions, &m.indices);
        let quarter = DMat4::from_rotation_z(std::f64::consts::FRAC_PI_2);
        let d = c.displacement(&quarter);
        assert!(!d.passes(c.tolerance()) && d.max > 0.015, "{}", mm(&d));
        // Its flips hold; revolution does not, and is dropped with its measurement.
        assert!(c.worst_displacement(&axis_aligned_transforms(Symmetry::Discrete)).max < 1e-9);
        let s = c.derive(Symmetry::ContinuousZ);
        print_table("box as continuous_z", &s);
        assert_eq!(s.kind, Symmetry::None);
        assert!(s.continuous.is_empty() && s.dropped().count() == 1);
        // A mug is no body of revolution (the handle), nor a box.
        let mug = procedural_mesh(Catalog::builtin().get("025_mug").unwrap());
        for kind in [Symmetry::ContinuousZ, Symmetry::Discrete] {
            let s = derive_symmetries(&mug.positions, &mug.indices, kind);
            print_table("mug", &s);
            assert_eq!(s.kind, Symmetry::None, "{kind:?}");
            assert!(s.discrete.is_empty() && s.continuous.is_empty() && s.dropped().count() == s.checks.len());
        }
        // Its flip about the body axis holds for 95% of the surface: the handle is caught by the
        // 99th percentile.
        let s = derive_symmetries(&mug.positions, &mug.indices, Symmetry::Discrete);
        let z = &s.checks[2].derived;
        assert!(z.p95 <= s.tolerance && z.p99 > 10.0 * s.tolerance && !z.passes(s.tolerance), "{}", mm(z));
    }

    #[test]
    fn procedural_stand_ins_keep_their_declared_symmetries() {
        for e in Catalog::builtin().entries() {
            let m = procedural_mesh(e);
            let s = derive_symmetries(&m.positions, &m.indices, e.symmetry);
            print_table(&e.id, &s);
            assert_derived_hold(&e.id, &m, &s);
            // The stand-ins are built on the model axes: every declared symmetry holds, and the
            // derived transforms are the axis-aligned ones.
            assert_eq!(s.kind, e.symmetry, "{}", e.id);
            assert!(s.dropped().next().is_none(), "{}", e.id);
            match e.symmetry {
                Symmetry::Discrete => {
                    assert_eq!(s.discrete.len(), 3);
                    for (t, want) in s.discrete.iter().zip(axis_aligned_transforms(Symmetry::Discrete)) {
                        assert!(t.abs_diff_eq(want, 1e-6), "{}: {t} vs {want}", e.id);
                    }
                }
                Symmetry::ContinuousZ => {
                    let a = s.continuous[0];
                    assert!(a.axis.abs_diff_eq(DVec3::Z, 1e-6) && a.offset.length() < 1e-6, "{}: {a:?}", e.id);
                }
                Symmetry::None => assert!(s.checks.is_empty()),
            }
        }
    }

    #[test]
    fn derivation_is_deterministic() {
        let m = box_mesh(DVec3::new(0.0447, 0.0505, 0.015), 13.0);
        let a = derive_symmetries(&m.positions, &m.indices, Symmetry::Discrete);
        let b = derive_symmetries(&m.positions, &m.indices, Symmetry::Discrete);
        assert_eq!(a, b);
    }

    /// The real scans (`YCB_DIR`, e.g. ../shared/assets/ycb; never committed): every derived symmetry
    /// holds within the tolerance (measured again with other samples), and what is kept is what the
    /// scans allow (see [`tolerance`] for the numbers): the gelatin box keeps its three flips and
    /// the sugar box and potted meat can their flip about the vertical, all turned or moved off the
    /// model axes; the dented cracker box and the out-of-round soup can keep nothing.
    #[test]
    fn real_scans_keep_only_symmetries_that_hold() {
        let Ok(dir) = std::env::var("YCB_DIR") else {
            eprintln!("skipped: YCB_DIR is not set (.ci/run sets it to ../shared/assets/ycb)");
            return;
        };
        let dir = std::path::PathBuf::from(dir);
        let expected_kept: [(&str, &[&str]); 5] = [
            ("003_cracker_box", &[]),
            ("004_sugar_box", &["flip z"]),
            ("005_tomato_soup_can", &[]),
            ("009_gelatin_box", &["flip x", "flip y", "flip z"]),
            ("010_potted_meat_can", &["flip z"]),
        ];
        for e in Catalog::builtin().entries() {
            let path = find_ycb_mesh(&dir, &e.id).unwrap_or_else(|t| panic!("{}: no mesh, tried {t:?}", e.id));
            let m = load_mesh(&path).unwrap();
            let started = std::time::Instant::now();
            let s = derive_symmetries(&m.positions, &m.indices, e.symmetry);
            let took = started.elapsed().as_secs_f64();
            print_table(&e.id, &s);
            eprintln!(
                "{:<22} diameter {:.1} mm, derived in {took:.2} s: discrete {:?} continuous {:?}",
                e.id,
                1e3 * s.diameter,
                s.discrete_row_major(),
                s.continuous
            );
            assert_derived_hold(&e.id, &m, &s);
            let kept: Vec<&str> = s.checks.iter().filter(|c| c.kept).map(|c| c.name).collect();
            let want = expected_kept.iter().find(|(id, _)| *id == e.id).map(|(_, k)| k.to_vec()).unwrap_or_default();
            assert_eq!(kept, want, "{}", e.id);
            assert_eq!(s.kind, if want.is_empty() { Symmetry::None } else { e.symmetry }, "{}", e.id);
            // The axis-aligned transforms fail, except the flip about z of the gelatin box (turned
            // about z) and of the potted meat can.
            let declared_held: Vec<&str> = s.checks.iter().filter(|c| c.declared.passes(s.tolerance)).map(|c| c.name).collect();
            let want = if ["009_gelatin_box", "010_potted_meat_can"].contains(&e.id.as_str()) { vec!["flip z"] } else { vec![] };
            assert_eq!(declared_held, want, "{}: the axis-aligned transforms that held", e.id);
        }
    }
}
