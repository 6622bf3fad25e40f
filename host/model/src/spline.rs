//! Clamped B-spline trajectory q(t) (paper §5, eq. (18)–(21)).
//!
//! Degree p ≤ [`MAX_DEGREE`], knot vector `y_1 = … = y_{p+1} = t0 ≤ interior ≤
//! y_{m+1} = … = y_{m+p+1} = t1` (eq. (18)); m coefficients per dimension.
//! `q_j(t) = Σ_i c_{i,j} N_i(t)` (eq. (20)); coefficients are stored basis-major,
//! `coeffs[i·dim + j]` = c_{j,i}, which is the paper's vector c of §6.
//!
//! The non-zero basis functions at t are N_{μ−p..=μ} on the knot span μ
//! (`y_μ ≤ t < y_{μ+1}`; t = t1 belongs to the last span); they and their
//! derivatives up to order 3 come from Cox–de Boor with derivatives (Piegl &
//! Tiller, *The NURBS Book*, A2.2 and eq. (2.9)), allocation-free.

use std::ops::{AddAssign, Mul};

use super::jet::Scalar;
use super::kinematics::JointState;
use super::lanes::F64x4;
use super::MAX_JOINTS;

mod fit;

/// Largest supported degree.
pub const MAX_DEGREE: usize = 5;
/// Most segments a uniform knot vector may have (10⁶: hours at a fine
/// spacing; more means times in ns or µs, and gigabytes of knots).
pub(crate) const MAX_SEGMENTS: usize = 1_000_000;
/// Highest derivative evaluated (q⃛).
pub(crate) const MAX_DERIV: usize = 3;

/// Why a spline could not be built or evaluated.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SplineError {
    /// Degree outside 1..=MAX_DEGREE.
    #[error("spline degree {0} is outside 1..={MAX_DEGREE}")]
    BadDegree(usize),
    /// A knot is NaN or infinite, or the knots decrease.
    #[error("knot {index} ({value}) is not finite or breaks the non-decreasing order")]
    BadKnot {
        /// Knot index.
        index: usize,
        /// Knot value.
        value: f64,
    },
    /// The knot vector is not clamped (first and last p+1 knots equal), is too
    /// short, or an interior knot has multiplicity above p.
    #[error("knot vector is not a clamped vector of degree {degree} (first/last {} knots equal, interior multiplicity ≤ {degree}, at least {} knots)", .degree + 1, 2 * (.degree + 1))]
    NotClamped {
        /// Degree.
        degree: usize,
    },
    /// `t0 >= t1` or a non-finite end.
    #[error("spline interval [{t0}, {t1}] is empty or not finite")]
    EmptyInterval {
        /// Start.
        t0: f64,
        /// End.
        t1: f64,
    },
    /// Knot spacing not finite and > 0.
    #[error("knot spacing {0} must be finite and > 0")]
    BadSpacing(f64),
    /// t outside the spline's interval.
    #[error("t = {t} is outside the spline interval [{t0}, {t1}]")]
    OutOfRange {
        /// The time asked for.
        t: f64,
        /// Start.
        t0: f64,
        /// End.
        t1: f64,
    },
    /// More than [`MAX_SEGMENTS`] knot intervals.
    #[error("a spline over [{t0}, {t1}] s with knots every {spacing} s would have {segments:.0} segments, more than {MAX_SEGMENTS} (timestamps in ns or µs instead of seconds?)")]
    TooManySegments {
        /// Start.
        t0: f64,
        /// End.
        t1: f64,
        /// Knot spacing asked for.
        spacing: f64,
        /// Segments it would need.
        segments: f64,
    },
    /// Dimension outside 1..=MAX_JOINTS.
    #[error("spline dimension {0} is outside 1..={MAX_JOINTS}")]
    BadDimension(usize),
    /// A buffer has the wrong length.
    #[error("{what} has {found} values; expected {expected}")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        found: usize,
    },
    /// The least-squares fit is singular (too few samples under basis function `coeff`).
    #[error("least-squares spline fit is singular at coefficient {coeff}: too few samples under its support")]
    Singular {
        /// Basis-function index.
        coeff: usize,
    },
}

/// A validated clamped knot vector with its degree.
#[derive(Clone, Debug, PartialEq)]
pub struct Knots {
    degree: usize,
    y: Vec<f64>,
}

impl Knots {
    /// Clamped knots on [t0, t1] with uniform interior knots: the interval is
    /// cut into `ceil((t1 − t0)/spacing)` equal segments (so the actual spacing
    /// is ≤ `spacing`, equal when it divides the interval).
    pub fn uniform(t0: f64, t1: f64, spacing: f64, degree: usize) -> Result<Self, SplineError> {
        if !(t0.is_finite() && t1.is_finite() && t0 < t1) {
            return Err(SplineError::EmptyInterval { t0, t1 });
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(SplineError::BadSpacing(spacing));
        }
        let segments = (((t1 - t0) / spacing) * (1.0 - 1e-12)).ceil().max(1.0);
        if segments > MAX_SEGMENTS as f64 {
            return Err(SplineError::TooManySegments {
                t0,
                t1,
                spacing,
                segments,
            });
        }
        let segments = segments as usize;
        let h = (t1 - t0) / segments as f64;
        let mut y = vec![t0; degree + 1];
        y.extend((1..segments).map(|i| t0 + i as f64 * h));
        y.extend(std::iter::repeat_n(t1, degree + 1));
        Self::new(degree, y)
    }

    /// An arbitrary clamped knot vector (eq. (18)).
    pub fn new(degree: usize, y: Vec<f64>) -> Result<Self, SplineError> {
        if !(1..=MAX_DEGREE).contains(&degree) {
            return Err(SplineError::BadDegree(degree));
        }
        for (i, &v) in y.iter().enumerate() {
            if !v.is_finite() || (i > 0 && v < y[i - 1]) {
                return Err(SplineError::BadKnot { index: i, value: v });
            }
        }
        let p = degree;
        if y.len() < 2 * (p + 1) {
            return Err(SplineError::NotClamped { degree });
        }
        let (t0, t1) = (y[0], y[y.len() - 1]);
        if t0 >= t1 {
            return Err(SplineError::EmptyInterval { t0, t1 });
        }
        let m = y.len() - p - 1;
        if y[p] != t0 || y[m] != t1 || y[p + 1] == t0 || y[m - 1] == t1 {
            return Err(SplineError::NotClamped { degree });
        }
        // Interior multiplicity ≤ p keeps q(t) continuous.
        let mut run = 1;
        for i in p + 2..m {
            run = if y[i] == y[i - 1] { run + 1 } else { 1 };
            if run > p {
                return Err(SplineError::NotClamped { degree });
            }
        }
        Ok(Self { degree, y })
    }

    /// Degree p.
    pub fn degree(&self) -> usize {
        self.degree
    }
    /// The knot vector.
    pub fn knots(&self) -> &[f64] {
        &self.y
    }
    /// Number of basis functions m.
    pub fn num_coeffs(&self) -> usize {
        self.y.len() - self.degree - 1
    }
    /// Start t0.
    pub fn start(&self) -> f64 {
        self.y[0]
    }
    /// End t1.
    pub fn end(&self) -> f64 {
        self.y[self.y.len() - 1]
    }
    /// Whether t0 ≤ t ≤ t1.
    pub fn contains(&self, t: f64) -> bool {
        t >= self.start() && t <= self.end()
    }

    /// Knot span μ (p ≤ μ ≤ m−1) with y_μ ≤ t < y_{μ+1}; t1 maps to m−1.
    pub fn span(&self, t: f64) -> Result<usize, SplineError> {
        if !self.contains(t) {
            return Err(SplineError::OutOfRange {
                t,
                t0: self.start(),
                t1: self.end(),
            });
        }
        let p = self.degree;
        let m = self.num_coeffs();
        Ok(p + self.y[p + 1..m].partition_point(|&u| u <= t))
    }

    /// The p+1 non-zero basis functions at t and their derivatives up to order 3.
    pub fn basis(&self, t: f64, out: &mut Basis) -> Result<(), SplineError> {
        let span = self.span(t)?;
        ders_basis_funs(&self.y, self.degree, span, t, &mut out.d);
        out.first = span - self.degree;
        out.count = self.degree + 1;
        Ok(())
    }
}

/// Non-zero basis functions at one t: `d[k][j]` = k-th derivative of
/// N_{first+j}(t), j < count = p+1, k ≤ 3 (zero for k > p).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Basis {
    /// Index of the first non-zero basis function.
    pub first: usize,
    /// Number of non-zero basis functions (p + 1).
    pub count: usize,
    /// Values and derivatives.
    pub d: [[f64; MAX_DEGREE + 1]; MAX_DERIV + 1],
}

/// The non-zero basis functions of four samples of one knot span, lane by
/// lane ([`crate::lanes`]): `d[k][j]` as in [`Basis`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Basis4 {
    /// Index of the first non-zero basis function (the same for every lane).
    pub first: usize,
    /// Number of non-zero basis functions (p + 1).
    pub count: usize,
    /// Values and derivatives.
    pub d: [[F64x4; MAX_DEGREE + 1]; MAX_DERIV + 1],
}

/// The non-zero basis functions of every knot span as polynomials, for
/// evaluating many times on one knot vector (the calibration evaluates every
/// IMU sample at every cost and linearisation, docs/model.md §5).
///
/// On span μ each N_{μ−p+a} is a polynomial of degree p in s = t − y_μ, so
/// its k-th derivative is exactly Σ_{i=0}^{p−k} N_{μ−p+a}^{(k+i)}(y_μ) sⁱ/i!
/// (Taylor at the span's left end, right-hand derivatives). The coefficients
/// come once per knot vector from the Cox–de Boor recursion of
/// [`Knots::basis`] (derivatives up to order p); a sample then costs the span
/// search and a few Horner steps instead of the Cox–de Boor table and its
/// divisions. Any clamped knot vector (uniform or not); the values equal
/// [`Knots::basis`] to rounding.
#[derive(Clone, Debug)]
pub struct SpanPolynomials {
    knots: Knots,
    /// Per span μ − p: `[k][a][i]` = N_{μ−p+a}^{(k+i)}(y_μ)/i! (zero on empty spans).
    coef: Vec<SpanCoeffs>,
}

type SpanCoeffs = [[[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1]; MAX_DERIV + 1];

impl SpanPolynomials {
    /// The polynomials of every span of `knots`.
    pub fn new(knots: &Knots) -> Self {
        const W: usize = MAX_DEGREE + 1;
        let (p, m, y) = (knots.degree(), knots.num_coeffs(), knots.knots());
        let coef = (p..m)
            .map(|mu| {
                let mut c = [[[0.0; W]; W]; MAX_DERIV + 1];
                // an empty span (repeated knot) is never a sample's span
                if y[mu] < y[mu + 1] {
                    let mut d = [[0.0; W]; W];
                    ders_basis_funs_upto(y, p, mu, y[mu], &mut d);
                    for (k, ck) in c.iter_mut().enumerate().take(MAX_DERIV.min(p) + 1) {
                        for (a, cka) in ck.iter_mut().enumerate().take(p + 1) {
                            let mut fact = 1.0;
                            for i in 0..=p - k {
                                fact *= i.max(1) as f64;
                                cka[i] = d[k + i][a] / fact;
                            }
                        }
                    }
                }
                c
            })
            .collect();
        Self {
            knots: knots.clone(),
            coef,
        }
    }

    /// The knots.
    pub fn knots(&self) -> &Knots {
        &self.knots
    }

    /// [`Knots::basis`] at t from the span polynomials.
    pub fn basis(&self, t: f64, out: &mut Basis) -> Result<(), SplineError> {
        let mu = self.knots.span(t)?;
        let p = self.knots.degree;
        let (s, c) = (t - self.knots.y[mu], &self.coef[mu - p]);
        match p {
            1 => horner::<1, f64>(c, s, &mut out.d),
            2 => horner::<2, f64>(c, s, &mut out.d),
            3 => horner::<3, f64>(c, s, &mut out.d),
            4 => horner::<4, f64>(c, s, &mut out.d),
            _ => horner::<5, f64>(c, s, &mut out.d),
        }
        out.first = mu - p;
        out.count = p + 1;
        Ok(())
    }

    /// The span μ of t ([`Knots::span`]), tried first at `hint` (the span
    /// of the previous of many ordered times).
    #[inline]
    pub fn span_near(&self, t: f64, hint: usize) -> Result<usize, SplineError> {
        let (y, p, m) = (&self.knots.y, self.knots.degree, self.knots.num_coeffs());
        if (p..m).contains(&hint)
            && y[hint] <= t
            && (t < y[hint + 1] || (hint + 1 == m && t <= y[m]))
        {
            return Ok(hint);
        }
        self.knots.span(t)
    }

    /// [`Self::basis`] of four times in the span μ, lane by lane
    /// (bit-identical to four scalar calls; [`crate::lanes`]).
    pub fn basis_x4(&self, mu: usize, t: F64x4, out: &mut Basis4) {
        let p = self.knots.degree;
        let (s, c) = (t - self.knots.y[mu], &self.coef[mu - p]);
        match p {
            1 => horner::<1, F64x4>(c, s, &mut out.d),
            2 => horner::<2, F64x4>(c, s, &mut out.d),
            3 => horner::<3, F64x4>(c, s, &mut out.d),
            4 => horner::<4, F64x4>(c, s, &mut out.d),
            _ => horner::<5, F64x4>(c, s, &mut out.d),
        }
        out.first = mu - p;
        out.count = p + 1;
    }
}

/// The rows of [`Basis::d`] at s from one span's coefficients (degree P),
/// for one time (f64) or four ([`F64x4`]).
#[inline(always)]
fn horner<const P: usize, S: Scalar>(
    c: &SpanCoeffs,
    s: S,
    d: &mut [[S; MAX_DEGREE + 1]; MAX_DERIV + 1],
) {
    *d = [[S::cst(0.0); MAX_DEGREE + 1]; MAX_DERIV + 1];
    for k in 0..=MAX_DERIV.min(P) {
        for a in 0..=P {
            let ca = &c[k][a];
            let mut v = S::cst(ca[P - k]);
            for i in (0..P - k).rev() {
                v = v * s + ca[i];
            }
            d[k][a] = v;
        }
    }
}

/// Non-zero basis functions of degree p on span μ and their derivatives.
///
/// Cox–de Boor builds the triangular table `ndu[r][j]` = N_{μ−j+r, j}(u) for
/// degrees j = 0..p (The NURBS Book A2.2) and keeps the inverted knot
/// differences; the k-th derivative then follows from the degree p−k values by
/// k steps of N^{(m)}_{i,q} = q [N^{(m−1)}_{i,q−1}/(u_{i+q} − u_i) −
/// N^{(m−1)}_{i+1,q−1}/(u_{i+q+1} − u_{i+1})]. Rows k > p stay zero.
#[inline]
fn ders_basis_funs(y: &[f64], p: usize, mu: usize, u: f64, ders: &mut [[f64; MAX_DEGREE + 1]; 4]) {
    ders_basis_funs_upto(y, p, mu, u, ders);
}

/// [`ders_basis_funs`] into `ders.len()` rows: derivatives up to order
/// min(rows − 1, p) (the same operations for the rows both compute).
#[inline(always)]
fn ders_basis_funs_upto<const R: usize>(
    y: &[f64],
    p: usize,
    mu: usize,
    u: f64,
    ders: &mut [[f64; MAX_DEGREE + 1]; R],
) {
    const W: usize = MAX_DEGREE + 1;
    let mut ndu = [[0.0f64; W]; W];
    // inv[j][r] = 1 / (y[μ+r+1] − y[μ+1−j+r]), r < j: always > 0 on a non-empty span.
    let mut inv = [[0.0f64; W]; W];
    let mut left = [0.0f64; W];
    let mut right = [0.0f64; W];
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = u - y[mu + 1 - j];
        right[j] = y[mu + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let iv = 1.0 / (right[r + 1] + left[j - r]);
            inv[j][r] = iv;
            let temp = ndu[r][j - 1] * iv;
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    *ders = [[0.0; W]; R];
    for r in 0..=p {
        ders[0][r] = ndu[r][p];
    }
    for k in 1..=(R - 1).min(p) {
        let q0 = p - k;
        let mut v = [0.0f64; W];
        for r in 0..=q0 {
            v[r] = ndu[r][q0];
        }
        for q in q0 + 1..=p {
            let mut nv = [0.0f64; W];
            for r in 0..=q {
                let mut t = 0.0;
                if r >= 1 {
                    t += v[r - 1] * inv[q][r - 1];
                }
                if r < q {
                    t -= v[r] * inv[q][r];
                }
                nv[r] = q as f64 * t;
            }
            v = nv;
        }
        ders[k][..=p].copy_from_slice(&v[..=p]);
    }
}

/// A dim-dimensional clamped B-spline (dim ≤ [`MAX_JOINTS`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Spline {
    knots: Knots,
    dim: usize,
    coeffs: Vec<f64>,
}

impl Spline {
    /// A spline from its coefficients (`coeffs[i·dim + j]`, m·dim values).
    pub fn new(knots: Knots, dim: usize, coeffs: Vec<f64>) -> Result<Self, SplineError> {
        if !(1..=MAX_JOINTS).contains(&dim) {
            return Err(SplineError::BadDimension(dim));
        }
        let expected = knots.num_coeffs() * dim;
        if coeffs.len() != expected {
            return Err(SplineError::LengthMismatch {
                what: "coefficient vector",
                expected,
                found: coeffs.len(),
            });
        }
        Ok(Self { knots, dim, coeffs })
    }

    /// The knots.
    pub fn knots(&self) -> &Knots {
        &self.knots
    }
    /// Dimension (number of joints).
    pub fn dim(&self) -> usize {
        self.dim
    }
    /// Coefficients, `coeffs[i·dim + j]` = c_{j,i}.
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }
    /// Mutable coefficients (same layout).
    pub fn coeffs_mut(&mut self) -> &mut [f64] {
        &mut self.coeffs
    }

    /// q, q̇, q̈, q⃛ at t from precomputed basis functions (see [`Knots::basis`]).
    pub fn evaluate_basis(&self, basis: &Basis, out: &mut JointState) {
        let rows: [&mut [f64; MAX_JOINTS]; 4] =
            [&mut out.q, &mut out.qd, &mut out.qdd, &mut out.qddd];
        for (k, row) in rows.into_iter().enumerate() {
            row.fill(0.0);
            self.add_row(basis.first, &basis.d[k][..basis.count], row);
        }
    }

    /// Adds Σ_a w_a c_{first+a, j} to `row[j]` (j < dim, a in the weights'
    /// order): one derivative row from a basis's weights of that order, in
    /// `f64` or in the lanes of [`F64x4`] (the same operations, so the same
    /// bits lane by lane).
    #[inline(always)]
    fn add_row<S>(&self, first: usize, weights: &[S], row: &mut [S])
    where
        S: Copy + AddAssign + Mul<f64, Output = S>,
    {
        let dim = self.dim;
        for (a, &w) in weights.iter().enumerate() {
            let c = &self.coeffs[(first + a) * dim..(first + a + 1) * dim];
            for (r, &cj) in row[..dim].iter_mut().zip(c) {
                *r += w * cj;
            }
        }
    }

    /// [`Self::evaluate_basis`] of four samples of one knot span, lane by
    /// lane (bit-identical to four scalar calls; [`crate::lanes`]).
    pub fn evaluate_basis_x4(&self, basis: &Basis4, out: &mut JointState<F64x4>) {
        let rows: [&mut [F64x4; MAX_JOINTS]; 4] =
            [&mut out.q, &mut out.qd, &mut out.qdd, &mut out.qddd];
        for (k, row) in rows.into_iter().enumerate() {
            row.fill(F64x4::splat(0.0));
            self.add_row(basis.first, &basis.d[k][..basis.count], row);
        }
    }

    /// The derivative rows `orders` (0: q, 1: q̇, 2: q̈, 3: q⃛) at four
    /// times, one per lane of `out[o][j]` (joint j of order `orders[o]`),
    /// by `spans` (the span polynomials of this spline's knots): one
    /// four-lane basis when the four share a knot span, else lane by lane;
    /// either way each lane has the bits of [`Self::evaluate_basis`]'s row.
    /// `hint` is the span tried first and is left at the last lane's. A
    /// lane outside the knots is zero and false in the returned mask;
    /// entries beyond `dim` are left as they are.
    pub fn rows_x4<const D: usize>(
        &self,
        spans: &SpanPolynomials,
        u: F64x4,
        orders: [usize; D],
        hint: &mut usize,
        out: &mut [[F64x4; MAX_JOINTS]; D],
    ) -> [bool; 4] {
        let dim = self.dim;
        let mu = u.0.map(|ul| spans.span_near(ul, *hint).ok());
        *hint = mu[3].unwrap_or(*hint);
        if let Some(m) = mu[0].filter(|_| mu.iter().all(|&v| v == mu[0])) {
            let mut b4 = Basis4::default();
            spans.basis_x4(m, u, &mut b4);
            for (row, &k) in out.iter_mut().zip(&orders) {
                row[..dim].fill(F64x4::splat(0.0));
                self.add_row(b4.first, &b4.d[k][..b4.count], row);
            }
            return [true; 4];
        }
        let mut inside = [false; 4];
        let mut b = Basis::default();
        for l in 0..4 {
            inside[l] = spans.basis(u.lane(l), &mut b).is_ok();
            for (row, &k) in out.iter_mut().zip(&orders) {
                let mut one = [0.0; MAX_JOINTS];
                if inside[l] {
                    self.add_row(b.first, &b.d[k][..b.count], &mut one);
                }
                for (r, v) in row[..dim].iter_mut().zip(one) {
                    r.0[l] = v;
                }
            }
        }
        inside
    }

    /// q, q̇, q̈, q⃛ at t (entries beyond `dim` are zero).
    pub fn evaluate(&self, t: f64, out: &mut JointState) -> Result<(), SplineError> {
        let mut b = Basis::default();
        self.knots.basis(t, &mut b)?;
        self.evaluate_basis(&b, out);
        Ok(())
    }

    /// q, q̇, q̈, q⃛ at t clamped into the span (the end states, derivatives
    /// included, outside it). Never fails: the knots of a `Spline` always
    /// have a non-empty span.
    pub fn evaluate_clamped(&self, t: f64, out: &mut JointState) {
        let (t0, t1) = (self.knots.start(), self.knots.end());
        let mut b = Basis::default();
        // A clamped t is inside [t0, t1], where the basis is defined.
        if self.knots.basis(t.clamp(t0, t1), &mut b).is_ok() {
            self.evaluate_basis(&b, out);
        }
    }

    /// The trajectory at any t: the spline inside its span, at rest at the
    /// end poses outside it (q̇ = q̈ = q⃛ = 0). The one definition of the
    /// motion before and after a planned trajectory (simulator, recorder,
    /// effects).
    pub fn state_at(&self, t: f64, out: &mut JointState) {
        self.evaluate_clamped(t, out);
        self.rest_outside(t, out);
    }

    /// [`Self::state_at`] with the basis from `spans`, the span polynomials
    /// of this spline's knots (equal to rounding; for many evaluations).
    ///
    /// # Panics
    /// If `spans` was built for other knots.
    #[track_caller]
    pub fn state_at_spans(&self, spans: &SpanPolynomials, t: f64, out: &mut JointState) {
        let (t0, t1) = (self.knots.start(), self.knots.end());
        let k = spans.knots();
        assert!(
            (k.degree, k.y.len(), k.start(), k.end())
                == (self.knots.degree, self.knots.y.len(), t0, t1),
            "span polynomials of other knots"
        );
        let mut b = Basis::default();
        if spans.basis(t.clamp(t0, t1), &mut b).is_ok() {
            self.evaluate_basis(&b, out);
        }
        self.rest_outside(t, out);
    }

    /// Zero q̇, q̈, q⃛ outside the span (at rest at the end poses).
    fn rest_outside(&self, t: f64, out: &mut JointState) {
        if t < self.knots.start() || t > self.knots.end() {
            out.qd = Default::default();
            out.qdd = Default::default();
            out.qddd = Default::default();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn irregular() -> Knots {
        Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.2, 2.0, 2.0, 2.0, 2.0],
        )
        .unwrap()
    }

    #[test]
    fn partition_of_unity_and_local_support() {
        for knots in [
            irregular(),
            Knots::uniform(-1.0, 4.5, 1.0, 3).unwrap(),
            Knots::uniform(0.0, 3.0, 0.7, 5).unwrap(),
            Knots::uniform(0.0, 3.0, 0.5, 1).unwrap(),
        ] {
            let mut b = Basis::default();
            for s in 0..=200 {
                let t = knots.start() + (knots.end() - knots.start()) * s as f64 / 200.0;
                knots.basis(t, &mut b).unwrap();
                let sum: f64 = b.d[0][..b.count].iter().sum();
                assert!((sum - 1.0).abs() < 1e-14, "sum {sum} at {t}");
                for k in 1..=3 {
                    let ds: f64 = b.d[k][..b.count].iter().sum();
                    assert!(ds.abs() < 1e-9, "Σ N^({k}) = {ds} at {t}");
                }
                assert!(b.d[0][..b.count].iter().all(|&v| v >= -1e-15));
                // local support (21): N_i > 0 only on (y_i, y_{i+p+1}).
                let y = knots.knots();
                for a in 0..b.count {
                    let i = b.first + a;
                    assert!(t >= y[i] && t <= y[i + knots.degree() + 1]);
                }
            }
        }
    }

    /// `rows_x4` gives each lane the bits of the scalar rows (the span
    /// polynomials' basis, `evaluate_basis`), for four
    /// times in one span, across spans, and partly outside the knots.
    #[test]
    fn four_lane_rows_are_the_scalar_rows() {
        let knots = Knots::uniform(0.0, 3.0, 0.37, 5).unwrap();
        let (nc, dim) = (knots.num_coeffs(), 3);
        let coeffs: Vec<f64> = (0..nc * dim)
            .map(|i| ((i * 37) % 11) as f64 * 0.3 - 1.4)
            .collect();
        let spline = Spline::new(knots.clone(), dim, coeffs).unwrap();
        let spans = SpanPolynomials::new(&knots);
        let quads = [
            [0.40, 0.41, 0.45, 0.50],
            [0.30, 0.36, 0.38, 0.90],
            [2.9, 2.95, 3.0, 3.2],
            [-0.1, 0.0, 1.0, 2.0],
        ];
        let mut hint = 0;
        for u in quads {
            let mut out = [[F64x4::splat(7.0); MAX_JOINTS]; 3];
            let inside = spline.rows_x4(&spans, F64x4(u), [0, 1, 2], &mut hint, &mut out);
            for (l, &t) in u.iter().enumerate() {
                // the scalar path: the span polynomials' basis, evaluate_basis
                let (mut js, mut b) = (JointState::default(), Basis::default());
                let ok = spans.basis(t, &mut b).is_ok();
                if ok {
                    spline.evaluate_basis(&b, &mut js);
                }
                assert_eq!(inside[l], ok, "t {t}");
                for (o, row) in [js.q, js.qd, js.qdd].iter().enumerate() {
                    for j in 0..dim {
                        let want = if ok { row[j] } else { 0.0 };
                        assert_eq!(
                            out[o][j].lane(l).to_bits(),
                            want.to_bits(),
                            "t {t} order {o}"
                        );
                    }
                    // beyond dim: untouched
                    assert_eq!(out[o][dim].lane(l), 7.0);
                }
            }
        }
    }

    /// `span_near` finds `Knots::span` from any hint, and `basis_x4` is
    /// four scalar `basis` calls bit for bit (every degree, a double knot,
    /// the ends, knots themselves).
    #[test]
    fn span_hints_and_four_lane_bases_match_the_scalar_ones() {
        let double = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.1, 1.2, 2.0, 2.0, 2.0, 2.0],
        )
        .unwrap();
        let mut sets = vec![irregular(), double];
        sets.extend((1..=5).map(|p| Knots::uniform(0.0, 3.0, 0.37, p).unwrap()));
        for knots in sets {
            let poly = SpanPolynomials::new(&knots);
            let (t0, t1) = (knots.start(), knots.end());
            let mut ts: Vec<f64> = knots.knots().to_vec();
            ts.extend((0..=403).map(|i| t0 + (t1 - t0) * i as f64 / 403.0));
            let m = knots.num_coeffs();
            for &t in &ts {
                let want = knots.span(t).unwrap();
                for hint in 0..m + 2 {
                    assert_eq!(poly.span_near(t, hint).unwrap(), want, "t {t} hint {hint}");
                }
            }
            assert!(poly.span_near(t1 + 1.0, 0).is_err());
            for quad in ts.chunks(4) {
                let mu = knots.span(quad[0]).unwrap();
                let lanes: [f64; 4] = std::array::from_fn(|l| {
                    let t = quad[l.min(quad.len() - 1)];
                    if knots.span(t).unwrap() == mu {
                        t
                    } else {
                        quad[0]
                    }
                });
                let mut b4 = Basis4::default();
                poly.basis_x4(mu, F64x4(lanes), &mut b4);
                for (l, &t) in lanes.iter().enumerate() {
                    let mut b = Basis::default();
                    poly.basis(t, &mut b).unwrap();
                    assert_eq!((b4.first, b4.count), (b.first, b.count));
                    for k in 0..=MAX_DERIV {
                        for a in 0..=MAX_DEGREE {
                            assert_eq!(b4.d[k][a].lane(l).to_bits(), b.d[k][a].to_bits());
                        }
                    }
                }
            }
        }
    }

    /// The span polynomials give Knots::basis to rounding everywhere: at
    /// and between knots, at both ends, on irregular knots with a double
    /// knot, for every degree.
    #[test]
    fn span_polynomials_equal_cox_de_boor() {
        let double = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.1, 1.2, 2.0, 2.0, 2.0, 2.0],
        )
        .unwrap();
        let mut sets = vec![
            irregular(),
            double,
            Knots::uniform(-3.0, 297.0, 1.0, 3).unwrap(),
        ];
        sets.extend((1..=5).map(|p| Knots::uniform(0.0, 3.0, 0.37, p).unwrap()));
        for knots in sets {
            let poly = SpanPolynomials::new(&knots);
            let (t0, t1) = (knots.start(), knots.end());
            let h_min = knots
                .knots()
                .windows(2)
                .map(|w| w[1] - w[0])
                .filter(|&h| h > 0.0)
                .fold(f64::INFINITY, f64::min);
            let mut ts: Vec<f64> = knots.knots().to_vec();
            ts.extend((0..=4001).map(|i| t0 + (t1 - t0) * i as f64 / 4001.0));
            ts.extend(knots.knots().iter().map(|&y| (y - 1e-9).max(t0)));
            let (mut want, mut got) = (Basis::default(), Basis::default());
            for t in ts {
                knots.basis(t, &mut want).unwrap();
                poly.basis(t, &mut got).unwrap();
                assert_eq!((got.first, got.count), (want.first, want.count), "t = {t}");
                for k in 0..=3 {
                    // relative to the row's scale (the k-th derivative grows as h^-k)
                    let row = want.d[k][..want.count]
                        .iter()
                        .fold(0.0f64, |m, v| m.max(v.abs()));
                    let tol = 1e-14 * row.max(h_min.powi(-(k as i32)));
                    for a in 0..want.count {
                        let (g, w) = (got.d[k][a], want.d[k][a]);
                        assert!(
                            (g - w).abs() <= tol,
                            "p {} t {t} k {k} a {a}: {g} vs {w}",
                            knots.degree()
                        );
                    }
                }
            }
            assert!(poly.basis(t1 + 1e-9, &mut got).is_err());
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let knots = irregular();
        let m = knots.num_coeffs();
        let coeffs: Vec<f64> = (0..m)
            .map(|i| (1.3 * i as f64).sin() + 0.2 * i as f64)
            .collect();
        let s = Spline::new(knots, 1, coeffs).unwrap();
        let mut st = JointState::default();
        let h = 1e-5;
        // Points away from knots (where the cubic's q⃛ jumps).
        for &t in &[0.1, 0.55, 0.9, 1.15, 1.5, 1.93] {
            let mut e = |t: f64| {
                s.evaluate(t, &mut st).unwrap();
                [st.q[0], st.qd[0], st.qdd[0], st.qddd[0]]
            };
            let (fp, fm, f0) = (e(t + h), e(t - h), e(t));
            for k in 0..3 {
                let fd = (fp[k] - fm[k]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + f0[k + 1].abs());
                assert!(
                    (fd - f0[k + 1]).abs() < tol,
                    "order {} at {t}: {fd} vs {}",
                    k + 1,
                    f0[k + 1]
                );
            }
        }
    }

    #[test]
    fn outside_the_span_the_trajectory_rests_at_its_end_poses() {
        let knots = Knots::uniform(2.0, 9.0, 1.0, 3).unwrap();
        let m = knots.num_coeffs();
        let coeffs: Vec<f64> = (0..2 * m).map(|i| (0.7 * i as f64).sin()).collect();
        let s = Spline::new(knots, 2, coeffs).unwrap();
        let (mut inside, mut at, mut end) = Default::default();
        let mut rest = JointState::default();
        for t in [2.0, 3.3, 8.99, 9.0] {
            s.evaluate(t, &mut inside).unwrap();
            s.state_at(t, &mut at);
            assert_eq!(at, inside, "t = {t}");
            s.evaluate_clamped(t, &mut at);
            assert_eq!(at, inside, "t = {t}");
        }
        for (t, edge) in [(1.5, 2.0), (-40.0, 2.0), (9.0 + 1e-9, 9.0), (30.0, 9.0)] {
            s.evaluate(edge, &mut end).unwrap();
            s.evaluate_clamped(t, &mut at);
            assert_eq!(at, end, "clamped at t = {t}");
            s.state_at(t, &mut rest);
            assert_eq!(rest.q, end.q, "t = {t}");
            assert!(end.qd[..2].iter().any(|v| v.abs() > 1e-3), "a moving end");
            for d in [rest.qd, rest.qdd, rest.qddd] {
                assert_eq!(d, [0.0; crate::MAX_JOINTS], "at rest at t = {t}");
            }
        }
    }

    #[test]
    fn clamped_ends_interpolate_end_coefficients() {
        let knots = Knots::uniform(2.0, 9.0, 1.0, 3).unwrap();
        let m = knots.num_coeffs();
        assert_eq!(m, 7 + 3);
        let coeffs: Vec<f64> = (0..2 * m).map(|i| (0.7 * i as f64).cos()).collect();
        let s = Spline::new(knots, 2, coeffs.clone()).unwrap();
        let mut st = JointState::default();
        s.evaluate(2.0, &mut st).unwrap();
        assert!((st.q[0] - coeffs[0]).abs() < 1e-15 && (st.q[1] - coeffs[1]).abs() < 1e-15);
        s.evaluate(9.0, &mut st).unwrap();
        assert!((st.q[0] - coeffs[2 * m - 2]).abs() < 1e-14);
        assert!((st.q[1] - coeffs[2 * m - 1]).abs() < 1e-14);
        assert!(matches!(
            s.evaluate(9.0 + 1e-9, &mut st),
            Err(SplineError::OutOfRange { .. })
        ));
        assert!(matches!(
            s.evaluate(1.999, &mut st),
            Err(SplineError::OutOfRange { .. })
        ));
    }

    #[test]
    fn least_squares_fit_reproduces_polynomials_up_to_degree_p() {
        for p in 1..=5usize {
            let knots = Knots::uniform(0.0, 10.0, 1.3, p).unwrap();
            let poly = |t: f64| -> [f64; 2] {
                let mut a = 0.0;
                let mut b = 0.0;
                for k in 0..=p {
                    a += (0.3 + 0.1 * k as f64) * (t / 10.0).powi(k as i32);
                    b += (-0.5f64).powi(k as i32) * (t / 10.0 - 0.4).powi(k as i32);
                }
                [a, b]
            };
            let times: Vec<f64> = (0..=400)
                .map(|i| i as f64 * 0.025 + 0.01 * (i % 3) as f64)
                .map(|t: f64| t.min(10.0))
                .collect();
            let values: Vec<f64> = times.iter().flat_map(|&t| poly(t)).collect();
            let s = Spline::fit(knots, 2, &times, &values).unwrap();
            let mut st = JointState::default();
            for i in 0..=97 {
                let t = i as f64 * 10.0 / 97.0;
                s.evaluate(t, &mut st).unwrap();
                let want = poly(t);
                assert!((st.q[0] - want[0]).abs() < 1e-10, "p={p} t={t}");
                assert!((st.q[1] - want[1]).abs() < 1e-10, "p={p} t={t}");
            }
        }
    }

    #[test]
    fn fit_without_data_under_a_basis_function_is_singular() {
        let knots = Knots::uniform(0.0, 10.0, 1.0, 3).unwrap();
        let times = [0.0, 0.5, 1.0, 9.0, 10.0];
        let values = [0.0; 5];
        assert!(matches!(
            Spline::fit(knots, 1, &times, &values),
            Err(SplineError::Singular { .. })
        ));
    }

    #[test]
    fn knot_validation() {
        assert_eq!(
            Knots::uniform(0.0, 1.0, 1.0, 6),
            Err(SplineError::BadDegree(6))
        );
        assert!(matches!(
            Knots::uniform(1.0, 1.0, 1.0, 3),
            Err(SplineError::EmptyInterval { .. })
        ));
        assert!(matches!(
            Knots::uniform(0.0, 1.0, 0.0, 3),
            Err(SplineError::BadSpacing(_))
        ));
        // Issue 41: a minute in ns at 50 ms knots (1.2e12 segments, 10 TB
        // of knots) is refused before allocating.
        let e = Knots::uniform(0.0, 60e9, 0.05, 3).unwrap_err();
        assert!(matches!(e, SplineError::TooManySegments { .. }));
        assert!(
            e.to_string()
                .contains("more than 1000000 (timestamps in ns"),
            "{e}"
        );
        assert!(matches!(
            Knots::new(3, vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 1.0]),
            Err(SplineError::NotClamped { .. })
        ));
        assert!(matches!(
            Knots::new(2, vec![0.0, 0.0, 0.0, 0.6, 0.5, 1.0, 1.0, 1.0]),
            Err(SplineError::BadKnot { index: 4, .. })
        ));
        let k = Knots::uniform(0.0, 300.0, 1.0, 3).unwrap();
        assert_eq!(k.num_coeffs(), 303);
        assert_eq!(k.span(0.0), Ok(3));
        assert_eq!(k.span(1.0), Ok(4));
        assert_eq!(k.span(300.0), Ok(302));
    }
}
