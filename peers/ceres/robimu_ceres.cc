// An independent Ceres 2.1 implementation of robimu's calibration problem
// (docs/model.md §1–4, the AUBO i5 setup of §6), for the back-to-back speed
// comparison of issue 18 and as a second method for the estimate.
//
// It shares no code with robimu. The IMU frame's angular velocity and
// acceleration come from the link-by-link recursion of paper eq. (4)
// (robimu differentiates the screws of the product instead); derivatives by
// "hybrid autodiff with a hand chain rule": one Jet over (q, q̇, q̈, ε, g_xy),
// chained by hand through the B-spline basis to the control points and τ,
// and a small Jet per sensor model (eq. (6)).
//
// Whole process: read the session CSVs, build the problem, Levenberg–
// Marquardt with the chosen linear solver on all threads asked for, the
// marginal covariance of x (ceres::Covariance), write a result file in the
// shape of docs/model.md §8. The τ search and the knot choice are *not* done
// here: `--tau` and `--knot-spacing` take them from a robimu result (its
// `tau_initial`, `knot_spacing`), which leaves Ceres less work than robimu
// does (the comparison is conservative).
//
//   robimu_ceres SESSION --tau T --knot-spacing H --out RESULT.json
//                [--threads 2] [--solver sparse_schur|sparse_normal_cholesky|
//                 dense_schur|iterative_schur] [--covariance normal|sparse_qr|
//                 dense_svd|none] [--function-tolerance 1e-10]
//                [--initial-trust-region 1e4] [--full-report]
//
// Build: peers/ceres/build.sh (Debian: apt install libceres-dev).

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

constexpr int kJoints = 6;
constexpr int kDegree = 3;
constexpr int kEps = 21;   // the minimal ε set of docs/model.md §1 (Table II)
constexpr int kSensor = 12;  // γ(3), r(3), k(3), b(3) of one sensor
constexpr int kKinUsed = 3 * kJoints + kEps + 2;  // q, q̇, q̈, ε, g_xy
#ifndef KKIN
#define KKIN 48
#endif
constexpr int kKin = KKIN;  // Jet size: kKinUsed, padded to whole SIMD vectors
constexpr int kGi = 3 * kJoints + kEps;  // where g_x, g_y sit in the Jet
static_assert(kKin >= kKinUsed, "Jet too small");
constexpr double kG0 = 9.81;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr double kMargin = 0.05;  // docs/model.md §4.2

// AUBO i5 nominal standard DH (docs/model.md §6): θ0, d, a, α.
constexpr double kDh[kJoints][4] = {
    {kPi, 0.122, 0.0, -kPi / 2}, {-kPi / 2, 0.1215, 0.408, kPi},
    {0.0, 0.0, 0.376, kPi},      {-kPi / 2, 0.0, 0.0, -kPi / 2},
    {0.0, 0.1025, 0.0, kPi / 2}, {0.0, 0.094, 0.0, 0.0}};

// Noise (docs/model.md §6).
constexpr double kSigmaZ[6] = {0.38, 0.21, 0.19, 0.32 * kDeg, 0.47 * kDeg, 0.57 * kDeg};
constexpr double kSigmaQ[kJoints] = {0.0038 * kDeg, 0.0050 * kDeg, 0.0043 * kDeg,
                                     0.0105 * kDeg, 0.0101 * kDeg, 0.0086 * kDeg};

// ε index in the 21-vector for link i (0-based) and k (1..6), or -1.
int eps_index(int link, int k) {
  static const int table[kJoints][6] = {
      {0, -1, -1, -1, -1, 1},     {2, 3, -1, 4, -1, 5},     {6, 7, -1, 8, -1, 9},
      {10, 11, -1, 12, -1, 13},  {14, 15, -1, 16, -1, 17}, {18, 19, 20, -1, -1, -1}};
  return table[link][k - 1];
}

// --- Small rotations on column-major 3×3 arrays (R[3*col + row]) ----------

// R ← R · Rx(θ), R · Ry(θ), R · Rz(θ), given c = cos θ, s = sin θ.
template <typename T, typename S>
void post_rx(T* R, const S& c, const S& s) {
  for (int r = 0; r < 3; ++r) {
    T y = R[3 + r], z = R[6 + r];
    R[3 + r] = y * c + z * s;
    R[6 + r] = z * c - y * s;
  }
}
template <typename T, typename S>
void post_ry(T* R, const S& c, const S& s) {
  for (int r = 0; r < 3; ++r) {
    T x = R[r], z = R[6 + r];
    R[r] = x * c - z * s;
    R[6 + r] = x * s + z * c;
  }
}
template <typename T, typename S>
void post_rz(T* R, const S& c, const S& s) {
  for (int r = 0; r < 3; ++r) {
    T x = R[r], y = R[3 + r];
    R[r] = x * c + y * s;
    R[3 + r] = y * c - x * s;
  }
}
template <typename T>
void cross(const T* a, const T* b, T* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

// The IMU frame's angular velocity ω and specific force s in IMU axes
// (docs/model.md §1.5, §2), by the recursion of paper eq. (4): joint i turns
// about the z axis of the frame before it, through that frame's origin;
// each frame origin is carried by the body after the joint.
//   ω_i = ω_{i-1} + q̇_i z,  α_i = α_{i-1} + q̈_i z + q̇_i ω_{i-1} × z,
//   a_i = a_{i-1} + α_i × r + ω_i × (ω_i × r),  r = o_i − o_{i-1}.
// `in` = [q(6), q̇(6), q̈(6), ε(21), g_x, g_y].
template <typename T>
void imu_motion(const T* in, T* s_out, T* w_out) {
  const T* q = in;
  const T* qd = in + kJoints;
  const T* qdd = in + 2 * kJoints;
  const T* eps = in + 3 * kJoints;
  T R[9] = {T(1), T(0), T(0), T(0), T(1), T(0), T(0), T(0), T(1)};
  T om[3] = {T(0), T(0), T(0)}, al[3] = {T(0), T(0), T(0)}, acc[3] = {T(0), T(0), T(0)};
  for (int i = 0; i < kJoints; ++i) {
    const T z[3] = {R[6], R[7], R[8]};
    T oz[3];
    cross(om, z, oz);
    for (int r = 0; r < 3; ++r) {
      al[r] = al[r] + qdd[i] * z[r] + qd[i] * oz[r];
      om[r] = om[r] + qd[i] * z[r];
    }
    const T th = q[i] + kDh[i][0];
    post_rz(R, cos(th), sin(th));
    // Local offset of the next origin: Tz(d) Tx(a) → (a, 0, d), then the
    // error translation after Rx(α): Rx(α) (ε1, ε2, ε3).
    T e[3] = {T(0), T(0), T(0)};
    for (int k = 0; k < 3; ++k) {
      int j = eps_index(i, k + 1);
      if (j >= 0) e[k] = eps[j];
    }
    const double ca = std::cos(kDh[i][3]), sa = std::sin(kDh[i][3]);
    const T off[3] = {kDh[i][2] + e[0], e[1] * ca - e[2] * sa, kDh[i][1] + e[1] * sa + e[2] * ca};
    T r[3];
    for (int k = 0; k < 3; ++k) r[k] = R[k] * off[0] + R[3 + k] * off[1] + R[6 + k] * off[2];
    T ar[3], wr[3], wwr[3];
    cross(al, r, ar);
    cross(om, r, wr);
    cross(om, wr, wwr);
    for (int k = 0; k < 3; ++k) acc[k] = acc[k] + ar[k] + wwr[k];
    // Rotation: Rx(α), then the error's Ry(ε4) Rz(ε5) Rx(ε6).
    post_rx(R, ca, sa);
    int j4 = eps_index(i, 4), j5 = eps_index(i, 5), j6 = eps_index(i, 6);
    if (j4 >= 0) post_ry(R, cos(eps[j4]), sin(eps[j4]));
    if (j5 >= 0) post_rz(R, cos(eps[j5]), sin(eps[j5]));
    if (j6 >= 0) post_rx(R, cos(eps[j6]), sin(eps[j6]));
  }
  const T* g = in + 3 * kJoints + kEps;
  const T gv[3] = {g[0], g[1], -sqrt(kG0 * kG0 - g[0] * g[0] - g[1] * g[1])};
  for (int k = 0; k < 3; ++k) {
    T ws = T(0), ss = T(0);
    for (int r = 0; r < 3; ++r) {
      ws = ws + R[3 * k + r] * om[r];
      ss = ss + R[3 * k + r] * (acc[r] - gv[r]);
    }
    w_out[k] = ws;
    s_out[k] = ss;
  }
}

// Sensor model (docs/model.md §3): out = K Γ R v + b, p = [γ_yz, γ_zy, γ_zx,
// r_z, r_y, r_x, k_x, k_y, k_z, b_x, b_y, b_z].
template <typename T, typename V>
void sensor(const T* p, const V* v, T* out) {
  // R = Rz(rz) Ry(ry) Rx(rx) applied to v: Rx first.
  const T cx = cos(p[5]), sx = sin(p[5]), cy = cos(p[4]), sy = sin(p[4]), cz = cos(p[3]),
          sz = sin(p[3]);
  T a0 = T(0) + v[0], a1 = v[1] * cx - v[2] * sx, a2 = v[1] * sx + v[2] * cx;
  T b0 = a0 * cy + a2 * sy, b1 = a1, b2 = a2 * cy - a0 * sy;
  T c0 = b0 * cz - b1 * sz, c1 = b0 * sz + b1 * cz, c2 = b2;
  // Γ = [[1,0,0],[γyz,1,0],[−γzy,γzx,1]]
  T d0 = c0, d1 = p[0] * c0 + c1, d2 = c2 - p[1] * c0 + p[2] * c1;
  out[0] = p[6] * d0 + p[9];
  out[1] = p[7] * d1 + p[10];
  out[2] = p[8] * d2 + p[11];
}

// M = K Γ R of a sensor (∂out/∂v), row-major.
void sensor_matrix(const double* p, double* M) {
  for (int c = 0; c < 3; ++c) {
    double v[3] = {0, 0, 0}, out[3];
    v[c] = 1;
    double pz[kSensor];
    std::copy(p, p + kSensor, pz);
    pz[9] = pz[10] = pz[11] = 0;
    sensor(pz, v, out);
    for (int r = 0; r < 3; ++r) M[3 * r + c] = out[r];
  }
}

// --- Clamped B-spline (docs/model.md §4.3) --------------------------------

struct Knots {
  std::vector<double> y;
  int count() const { return int(y.size()) - kDegree - 1; }  // control points

  static Knots uniform(double t0, double t1, double spacing) {
    Knots k;
    size_t seg = std::max(1.0, std::ceil((t1 - t0) / spacing * (1.0 - 1e-12)));
    double h = (t1 - t0) / seg;
    for (int i = 0; i <= kDegree; ++i) k.y.push_back(t0);
    for (size_t i = 1; i < seg; ++i) k.y.push_back(t0 + i * h);
    for (int i = 0; i <= kDegree; ++i) k.y.push_back(t1);
    return k;
  }
  // μ with y[μ] ≤ u < y[μ+1], clamped to the valid spans.
  int span(double u) const {
    int n = count() - 1;
    if (u >= y[n + 1]) return n;
    if (u <= y[kDegree]) return kDegree;
    return int(std::upper_bound(y.begin(), y.end(), u) - y.begin()) - 1;
  }
  // ders[k][j]: k-th derivative of N_{μ−p+j} at u (The NURBS Book, A2.3);
  // the polynomial of span μ, also slightly outside it.
  void basis(int mu, double u, double ders[4][kDegree + 1]) const {
    const int p = kDegree;
    double ndu[p + 1][p + 1], left[p + 1], right[p + 1], a[2][p + 1];
    ndu[0][0] = 1.0;
    for (int j = 1; j <= p; ++j) {
      left[j] = u - y[mu + 1 - j];
      right[j] = y[mu + j] - u;
      double saved = 0.0;
      for (int r = 0; r < j; ++r) {
        ndu[j][r] = right[r + 1] + left[j - r];
        double temp = ndu[r][j - 1] / ndu[j][r];
        ndu[r][j] = saved + right[r + 1] * temp;
        saved = left[j - r] * temp;
      }
      ndu[j][j] = saved;
    }
    for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
    for (int r = 0; r <= p; ++r) {
      int s1 = 0, s2 = 1;
      a[0][0] = 1.0;
      for (int k = 1; k <= 3; ++k) {
        double d = 0.0;
        int rk = r - k, pk = p - k;
        if (r >= k) {
          a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
          d = a[s2][0] * ndu[rk][pk];
        }
        int j1 = rk >= -1 ? 1 : -rk;
        int j2 = (r - 1 <= pk) ? k - 1 : p - r;
        for (int j = j1; j <= j2; ++j) {
          a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
          d += a[s2][j] * ndu[rk + j][pk];
        }
        if (r <= pk) {
          a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
          d += a[s2][k] * ndu[r][pk];
        }
        ders[k][r] = d;
        std::swap(s1, s2);
      }
    }
    double f = p;
    for (int k = 1; k <= 3; ++k) {
      for (int j = 0; j <= p; ++j) ders[k][j] *= f;
      f *= p - k;
    }
  }
};

// --- Residuals ------------------------------------------------------------

// One IMU sample (docs/model.md §4.1): r = (h(t + τ, x) − z) / σ_z.
// Blocks: 4 control points (6 joints each), ε(21), g_xy(2), τ(1),
// accelerometer(12), gyroscope(12).
class ImuResidual final
    : public ceres::SizedCostFunction<6, kJoints, kJoints, kJoints, kJoints, kEps, 2, 1,
                                      kSensor, kSensor> {
 public:
  ImuResidual(const Knots* knots, int mu, double t, const double* z)
      : knots_(knots), mu_(mu), t_(t) {
    std::copy(z, z + 6, z_);
  }

  bool Evaluate(double const* const* par, double* res, double** jac) const override {
    const double tau = par[6][0];
    double N[4][kDegree + 1];
    knots_->basis(mu_, t_ + tau, N);
    double qd4[4][kJoints];  // q, q̇, q̈, q⃛
    for (int k = 0; k < 4; ++k)
      for (int j = 0; j < kJoints; ++j) {
        double v = 0;
        for (int b = 0; b <= kDegree; ++b) v += N[k][b] * par[b][j];
        qd4[k][j] = v;
      }
    double s[3], w[3], Ma[9], Mw[9];
    using Jet = ceres::Jet<double, kKin>;
    Jet sj[3], wj[3];
    if (jac == nullptr) {
      double in[kKin];
      for (int k = 0; k < 3; ++k) std::copy(qd4[k], qd4[k] + kJoints, in + k * kJoints);
      std::copy(par[4], par[4] + kEps, in + 3 * kJoints);
      in[kGi] = par[5][0];
      in[kGi + 1] = par[5][1];
      imu_motion(in, s, w);
    } else {
      Jet in[kKin];
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < kJoints; ++j) in[k * kJoints + j] = Jet(qd4[k][j], k * kJoints + j);
      for (int j = 0; j < kEps; ++j) in[3 * kJoints + j] = Jet(par[4][j], 3 * kJoints + j);
      in[kGi] = Jet(par[5][0], kGi);
      in[kGi + 1] = Jet(par[5][1], kGi + 1);
      imu_motion(in, sj, wj);
      for (int k = 0; k < 3; ++k) {
        s[k] = sj[k].a;
        w[k] = wj[k].a;
      }
    }
    // Sensor models, with their own 12-wide Jets when Jacobians are asked.
    using SJet = ceres::Jet<double, kSensor>;
    double h[6];
    if (jac == nullptr || (jac[7] == nullptr && jac[8] == nullptr)) {
      sensor(par[7], s, h);
      sensor(par[8], w, h + 3);
    } else {
      for (int sen = 0; sen < 2; ++sen) {
        SJet p[kSensor], out[3];
        for (int k = 0; k < kSensor; ++k) p[k] = SJet(par[7 + sen][k], k);
        sensor(p, sen == 0 ? s : w, out);
        double* J = jac[7 + sen];
        double* Jo = jac[8 - sen];
        for (int r = 0; r < 3; ++r) {
          h[3 * sen + r] = out[r].a;
          for (int k = 0; k < kSensor; ++k) {
            if (J) J[(3 * sen + r) * kSensor + k] = out[r].v[k] / kSigmaZ[3 * sen + r];
            if (Jo) Jo[(3 * sen + r) * kSensor + k] = 0.0;
          }
        }
      }
    }
    for (int r = 0; r < 6; ++r) res[r] = (h[r] - z_[r]) / kSigmaZ[r];
    if (jac == nullptr) return true;
    // ∂r/∂(kinematic inputs): rows M_a ∂s, M_w ∂ω, whitened.
    sensor_matrix(par[7], Ma);
    sensor_matrix(par[8], Mw);
    Eigen::Matrix<double, 6, kKin, Eigen::RowMajor> D;
    for (int r = 0; r < 3; ++r) {
      D.row(r) = (Ma[3 * r] * sj[0].v + Ma[3 * r + 1] * sj[1].v + Ma[3 * r + 2] * sj[2].v)
                     .transpose() / kSigmaZ[r];
      D.row(3 + r) = (Mw[3 * r] * wj[0].v + Mw[3 * r + 1] * wj[1].v + Mw[3 * r + 2] * wj[2].v)
                         .transpose() / kSigmaZ[3 + r];
    }
    // Hand chain rule through the spline: q^(k) = Σ_b N^(k)_b c_b.
    for (int b = 0; b <= kDegree; ++b) {
      if (!jac[b]) continue;
      for (int r = 0; r < 6; ++r)
        for (int j = 0; j < kJoints; ++j)
          jac[b][r * kJoints + j] = D(r, j) * N[0][b] + D(r, kJoints + j) * N[1][b] +
                                    D(r, 2 * kJoints + j) * N[2][b];
    }
    if (jac[4])
      for (int r = 0; r < 6; ++r)
        for (int j = 0; j < kEps; ++j) jac[4][r * kEps + j] = D(r, 3 * kJoints + j);
    if (jac[5])
      for (int r = 0; r < 6; ++r) {
        jac[5][2 * r] = D(r, kGi);
        jac[5][2 * r + 1] = D(r, kGi + 1);
      }
    if (jac[6])
      for (int r = 0; r < 6; ++r) {
        double v = 0;
        for (int j = 0; j < kJoints; ++j)
          v += D(r, j) * qd4[1][j] + D(r, kJoints + j) * qd4[2][j] +
               D(r, 2 * kJoints + j) * qd4[3][j];
        jac[6][r] = v;
      }
    return true;
  }

 private:
  const Knots* knots_;
  int mu_;
  double t_;
  double z_[6];
};

// One joint sample: r = (q(t) − q̃) / σ_q, linear in the 4 control points.
class JointResidual final
    : public ceres::SizedCostFunction<kJoints, kJoints, kJoints, kJoints, kJoints> {
 public:
  JointResidual(const Knots& knots, double t, const double* q) {
    int mu = knots.span(t);
    double N[4][kDegree + 1];
    knots.basis(mu, t, N);
    std::copy(N[0], N[0] + 4, n_);
    std::copy(q, q + kJoints, q_);
  }
  bool Evaluate(double const* const* par, double* res, double** jac) const override {
    for (int j = 0; j < kJoints; ++j) {
      double v = 0;
      for (int b = 0; b < 4; ++b) v += n_[b] * par[b][j];
      res[j] = (v - q_[j]) / kSigmaQ[j];
    }
    if (jac)
      for (int b = 0; b < 4; ++b)
        if (jac[b])
          for (int r = 0; r < kJoints; ++r)
            for (int j = 0; j < kJoints; ++j)
              jac[b][r * kJoints + j] = r == j ? n_[b] / kSigmaQ[j] : 0.0;
    return true;
  }

 private:
  double n_[4];
  double q_[kJoints];
};

// Gaussian prior on one parameter block: r = (x − x̂) / σ.
class PriorResidual final : public ceres::CostFunction {
 public:
  PriorResidual(std::vector<double> mean, std::vector<double> sigma)
      : mean_(std::move(mean)), sigma_(std::move(sigma)) {
    set_num_residuals(int(mean_.size()));
    mutable_parameter_block_sizes()->push_back(int(mean_.size()));
  }
  bool Evaluate(double const* const* par, double* res, double** jac) const override {
    int n = int(mean_.size());
    for (int i = 0; i < n; ++i) res[i] = (par[0][i] - mean_[i]) / sigma_[i];
    if (jac && jac[0])
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) jac[0][i * n + j] = i == j ? 1.0 / sigma_[i] : 0.0;
    return true;
  }

 private:
  std::vector<double> mean_, sigma_;
};

// --- Input -----------------------------------------------------------------

// Rows of a session CSV (docs/model.md §7): the first `cols` numbers.
std::vector<std::vector<double>> read_csv(const std::string& path, int cols) {
  std::ifstream f(path);
  if (!f) {
    std::fprintf(stderr, "error: cannot read %s\n", path.c_str());
    std::exit(2);
  }
  std::vector<std::vector<double>> rows;
  std::string line;
  bool header = true;
  while (std::getline(f, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header) {
      header = false;
      continue;
    }
    std::vector<double> row(cols);
    const char* p = line.c_str();
    for (int c = 0; c < cols; ++c) {
      char* end;
      row[c] = std::strtod(p, &end);
      if (end == p) {
        std::fprintf(stderr, "error: %s: bad number in row %zu\n", path.c_str(), rows.size() + 1);
        std::exit(2);
      }
      p = *end == ',' ? end + 1 : end;
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

struct Param {
  std::string name;
  const char* unit;
  double prior, sigma;
};

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: robimu_ceres SESSION --tau T --knot-spacing H --out F [...]\n");
    return 2;
  }
  std::string session = argv[1], out, solver = "sparse_schur", cov = "normal";
  double tau0 = NAN, spacing = NAN, ftol = 1e-10, radius = 1e4;
  int threads = 2;
  std::string library = "suite_sparse";
  bool full_report = false;
  for (int i = 2; i < argc; i += 2) {
    std::string a = argv[i];
    if (a == "--full-report") {
      full_report = true;
      --i;
      continue;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "error: %s needs a value\n", a.c_str());
      return 2;
    }
    std::string v = argv[i + 1];
    if (a == "--tau") tau0 = std::atof(v.c_str());
    else if (a == "--knot-spacing") spacing = std::atof(v.c_str());
    else if (a == "--out") out = v;
    else if (a == "--threads") threads = std::atoi(v.c_str());
    else if (a == "--solver") solver = v;
    else if (a == "--covariance") cov = v;
    else if (a == "--function-tolerance") ftol = std::atof(v.c_str());
    else if (a == "--initial-trust-region") radius = std::atof(v.c_str());
    else if (a == "--sparse-library") library = v;
    else {
      std::fprintf(stderr, "error: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (std::isnan(tau0) || std::isnan(spacing) || out.empty()) {
    std::fprintf(stderr, "error: --tau, --knot-spacing and --out are required\n");
    return 2;
  }
  const double t_start = now();
  {
    // The peer knows the AUBO i5 setup of docs/model.md §6 only.
    std::ifstream f(session + "/session.toml");
    std::stringstream text;
    text << f.rdbuf();
    const std::string t = text.str();
    if (!f || t.find("robimu-session/1") == std::string::npos) {
      std::fprintf(stderr, "error: %s/session.toml: not a robimu-session/1 session\n",
                   session.c_str());
      return 2;
    }
    if (t.find("\"aubo_i5\"") == std::string::npos || t.find("[noise]") != std::string::npos ||
        t.find("gravity") != std::string::npos || t.find("[imu1]") != std::string::npos) {
      std::fprintf(stderr,
                   "error: %s: the Ceres peer knows only one IMU on the AUBO i5 with the "
                   "default noise and gravity (docs/model.md §6)\n",
                   session.c_str());
      return 2;
    }
  }
  auto joints = read_csv(session + "/joints.csv", 1 + kJoints);
  auto imu = read_csv(session + "/imu.csv", 7);
  const double t_read = now();
  if (joints.size() < 8 || imu.empty()) {
    std::fprintf(stderr, "error: too few samples\n");
    return 2;
  }
  const double t0 = joints.front()[0], t1 = joints.back()[0];
  const Knots knots = Knots::uniform(t0, t1, spacing);
  const int m = knots.count();

  // Start: control points at the Greville abscissae, joint samples
  // interpolated linearly (LM's first step fits them to the samples).
  std::vector<std::array<double, kJoints>> cps(m);
  for (int i = 0; i < m; ++i) {
    double xi = (knots.y[i + 1] + knots.y[i + 2] + knots.y[i + 3]) / 3.0;
    auto it = std::lower_bound(joints.begin(), joints.end(), xi,
                               [](const std::vector<double>& r, double t) { return r[0] < t; });
    size_t k = std::min<size_t>(std::max<ptrdiff_t>(it - joints.begin(), 1), joints.size() - 1);
    double f = (xi - joints[k - 1][0]) / (joints[k][0] - joints[k - 1][0]);
    for (int j = 0; j < kJoints; ++j)
      cps[i][j] = joints[k - 1][1 + j] * (1 - f) + joints[k][1 + j] * f;
  }

  // x and its prior (docs/model.md §5, §6), in §5 order.
  std::vector<Param> params;
  const char* eps_names[kEps] = {"eps_1_1", "eps_1_6", "eps_2_1", "eps_2_2", "eps_2_4",
                                 "eps_2_6", "eps_3_1", "eps_3_2", "eps_3_4", "eps_3_6",
                                 "eps_4_1", "eps_4_2", "eps_4_4", "eps_4_6", "eps_5_1",
                                 "eps_5_2", "eps_5_4", "eps_5_6", "eps_6_1", "eps_6_2",
                                 "eps_6_3"};
  const double imu_pos[3] = {0.0252, 0.0783, 0.0182};
  for (int i = 0; i < kEps; ++i) {
    const char* n = eps_names[i];
    bool length = n[6] <= '3';
    double prior = i >= 18 ? imu_pos[i - 18] : 0.0;
    double sigma = i >= 18 ? 0.01 : (length ? 0.001 : kDeg);
    params.push_back({n, length ? "m" : "rad", prior, sigma});
  }
  params.push_back({"g_x", "m/s^2", 0.0, 0.5});
  params.push_back({"g_y", "m/s^2", 0.0, 0.5});
  params.push_back({"tau", "s", 0.0, 1.0});
  for (int sen = 0; sen < 2; ++sen) {
    const std::string pre = sen == 0 ? "a" : "w";
    const double gsig = (sen == 0 ? 1.5 : 2.0) * kDeg;
    for (const char* ax : {"yz", "zy", "zx"}) params.push_back({"gamma_" + pre + "_" + ax, "rad", 0.0, gsig});
    params.push_back({"r_" + pre + "_z", "rad", kPi, 5 * kDeg});
    params.push_back({"r_" + pre + "_y", "rad", 0.0, 5 * kDeg});
    params.push_back({"r_" + pre + "_x", "rad", 0.0, 5 * kDeg});
    for (const char* ax : {"x", "y", "z"}) params.push_back({"k_" + pre + "_" + ax, "1", 1.0, 0.1});
    for (const char* ax : {"x", "y", "z"})
      params.push_back({"b_" + pre + "_" + ax, sen == 0 ? "m/s^2" : "rad/s", 0.0, sen == 0 ? 2.0 : 5 * kDeg});
  }
  // Parameter blocks: ε(21), g(2), τ(1), accelerometer(12), gyroscope(12).
  const int block_size[5] = {kEps, 2, 1, kSensor, kSensor};
  std::vector<double> x(params.size());
  for (size_t i = 0; i < x.size(); ++i) x[i] = params[i].prior;
  x[kEps + 2] = tau0;
  double* block[5];
  {
    int off = 0;
    for (int b = 0; b < 5; ++b) {
      block[b] = x.data() + off;
      off += block_size[b];
    }
  }


  ceres::Problem::Options popt;
  popt.enable_fast_removal = false;
  popt.disable_all_safety_checks = true;
  ceres::Problem problem(popt);
  for (auto& c : cps) problem.AddParameterBlock(c.data(), kJoints);
  for (int b = 0; b < 5; ++b) problem.AddParameterBlock(block[b], block_size[b]);
  for (const auto& row : joints) {
    int mu = knots.span(row[0]);
    problem.AddResidualBlock(new JointResidual(knots, row[0], row.data() + 1), nullptr,
                             cps[mu - 3].data(), cps[mu - 2].data(), cps[mu - 1].data(),
                             cps[mu].data());
  }
  int used = 0;
  for (const auto& row : imu) {
    double u = row[0] + tau0;
    if (u < t0 + kMargin || u > t1 - kMargin) continue;
    int mu = knots.span(u);
    problem.AddResidualBlock(new ImuResidual(&knots, mu, row[0], row.data() + 1), nullptr,
                             cps[mu - 3].data(), cps[mu - 2].data(), cps[mu - 1].data(),
                             cps[mu].data(), block[0], block[1], block[2], block[3], block[4]);
    ++used;
  }
  {
    int off = 0;
    for (int b = 0; b < 5; ++b) {
      std::vector<double> mean, sigma;
      for (int k = 0; k < block_size[b]; ++k) {
        mean.push_back(params[off + k].prior);
        sigma.push_back(params[off + k].sigma);
      }
      problem.AddResidualBlock(new PriorResidual(mean, sigma), nullptr, block[b]);
      off += block_size[b];
    }
  }
  const double t_setup = now();

  ceres::Solver::Options opt;
  opt.minimizer_type = ceres::TRUST_REGION;
  opt.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  opt.num_threads = threads;
  opt.max_num_iterations = 100;
  opt.function_tolerance = ftol;
  opt.initial_trust_region_radius = radius;
  opt.gradient_tolerance = 1e-12;
  opt.parameter_tolerance = 1e-12;
  if (solver == "sparse_normal_cholesky") opt.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  else if (solver == "sparse_schur") opt.linear_solver_type = ceres::SPARSE_SCHUR;
  else if (solver == "dense_schur") opt.linear_solver_type = ceres::DENSE_SCHUR;
  else if (solver == "iterative_schur") {
    opt.linear_solver_type = ceres::ITERATIVE_SCHUR;
    opt.preconditioner_type = ceres::SCHUR_JACOBI;
  } else {
    std::fprintf(stderr, "error: unknown --solver %s\n", solver.c_str());
    return 2;
  }
  if (library == "eigen") opt.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  else if (library == "cx_sparse") opt.sparse_linear_algebra_library_type = ceres::CX_SPARSE;
  else if (library != "suite_sparse") {
    std::fprintf(stderr, "error: unknown --sparse-library %s\n", library.c_str());
    return 2;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(opt, &problem, &summary);
  const double t_solve = now();
  std::fprintf(stderr, "%s\n", (full_report ? summary.FullReport() : summary.BriefReport()).c_str());
  if (!summary.IsSolutionUsable()) {
    std::fprintf(stderr, "error: the solve failed\n");
    return 1;
  }

  // Marginal covariance of x (docs/model.md §8): the x block of the inverse
  // Gauss–Newton matrix (paper eq. (24)). `normal` (default): the Jacobian
  // at the solution from Ceres, JᵀJ accumulated dense on `threads` threads,
  // Cholesky, x's columns of the inverse. `sparse_qr`, `dense_svd`:
  // ceres::Covariance with that algorithm (much slower here).
  const size_t n = x.size();
  std::vector<double> C(n * n, 0.0);
  bool have_cov = false;
  if (cov == "normal") {
    // Columns: the control points, then x. Every residual block's Jacobian
    // is evaluated once more at the solution (its cost function directly, on
    // `threads` threads) and its small dense BᵀB scattered into H.
    const int N = int(m * kJoints + n);
    const double* cp0 = cps[0].data();
    auto column = [&](const double* p) {
      return p >= cp0 && p < cp0 + m * kJoints ? int(p - cp0) : int(m * kJoints + (p - x.data()));
    };
    std::vector<ceres::ResidualBlockId> ids;
    problem.GetResidualBlocks(&ids);
    const double t_eval = now();
    std::vector<Eigen::MatrixXd> parts(threads, Eigen::MatrixXd::Zero(N, N));
    std::vector<std::thread> pool;
    for (int th = 0; th < threads; ++th)
      pool.emplace_back([&, th] {
        Eigen::MatrixXd& H = parts[th];
        Eigen::MatrixXd G;
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> B;
        std::vector<double*> blocks;
        std::vector<double> res, store;
        std::vector<double*> jac;
        std::vector<int> cols;
        for (size_t k = th; k < ids.size(); k += threads) {
          const ceres::CostFunction* f = problem.GetCostFunctionForResidualBlock(ids[k]);
          problem.GetParameterBlocksForResidualBlock(ids[k], &blocks);
          const auto& sizes = f->parameter_block_sizes();
          const int nr = f->num_residuals();
          int c = 0;
          for (int sz : sizes) c += sz;
          res.resize(nr);
          store.resize(size_t(nr) * c);
          jac.clear();
          cols.clear();
          int off = 0;
          for (size_t b = 0; b < sizes.size(); ++b) {
            jac.push_back(store.data() + size_t(nr) * off);
            for (int j = 0; j < sizes[b]; ++j) cols.push_back(column(blocks[b]) + j);
            off += sizes[b];
          }
          f->Evaluate(blocks.data(), res.data(), jac.data());
          B.resize(nr, c);
          off = 0;
          for (size_t b = 0; b < sizes.size(); ++b) {
            for (int r = 0; r < nr; ++r)
              for (int j = 0; j < sizes[b]; ++j) B(r, off + j) = jac[b][r * sizes[b] + j];
            off += sizes[b];
          }
          G.noalias() = B.transpose() * B;
          for (int a = 0; a < c; ++a) {
            double* col = H.data() + size_t(cols[a]) * N;  // column cols[a], lower part
            for (int b = a; b < c; ++b) col[cols[b]] += G(b, a);
          }
        }
      });
    for (auto& t : pool) t.join();
    for (int th = 1; th < threads; ++th) parts[0] += parts[th];
    const double t_acc = now();
    // Each block's columns increase, so each entry is (row ≥ column): lower.
    Eigen::LLT<Eigen::MatrixXd> llt(parts[0].selfadjointView<Eigen::Lower>());
    if (llt.info() != Eigen::Success) {
      std::fprintf(stderr, "error: the Gauss-Newton matrix is not positive definite\n");
      return 1;
    }
    Eigen::MatrixXd E = Eigen::MatrixXd::Zero(N, n);
    for (size_t k = 0; k < n; ++k) E(N - n + k, k) = 1.0;
    Eigen::MatrixXd X = llt.solve(E);
    if (full_report)
      std::fprintf(stderr, "covariance: Jacobians and JtJ %.3f s, Cholesky and solve %.3f s\n",
                   t_acc - t_eval, now() - t_acc);
    for (size_t i = 0; i < n; ++i)
      for (size_t k = 0; k < n; ++k) C[i * n + k] = X(N - n + i, k);
    have_cov = true;
  } else if (cov != "none") {
    ceres::Covariance::Options copt;
    copt.num_threads = threads;
    if (cov == "dense_svd") copt.algorithm_type = ceres::DENSE_SVD;
    else copt.algorithm_type = ceres::SPARSE_QR;
    ceres::Covariance covariance(copt);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (int a = 0; a < 5; ++a)
      for (int b = a; b < 5; ++b) pairs.emplace_back(block[a], block[b]);
    if (!covariance.Compute(pairs, &problem)) {
      std::fprintf(stderr, "error: covariance failed\n");
      return 1;
    }
    std::vector<const double*> blocks(block, block + 5);
    covariance.GetCovarianceMatrix(blocks, C.data());
    have_cov = true;
  }
  const double t_cov = now();

  std::ostringstream js;
  js.precision(17);
  js << "{\n  \"format\": \"robimu-result/1\",\n  \"producer\": \"peers/ceres robimu_ceres "
        "(Ceres "
     << CERES_VERSION_STRING << ")\",\n  \"parameters\": [\n";
  for (size_t i = 0; i < n; ++i) {
    double sig = have_cov ? std::sqrt(C[i * n + i]) : 0.0;
    js << "    {\"name\": \"" << params[i].name << "\", \"unit\": \"" << params[i].unit
       << "\", \"value\": " << x[i] << ", \"prior\": " << params[i].prior
       << ", \"prior_sigma\": " << params[i].sigma << ", \"sigma\": " << sig
       << ", \"frozen\": false}" << (i + 1 < n ? ",\n" : "\n");
  }
  js << "  ],\n  \"covariance\": {\"names\": [";
  for (size_t i = 0; i < n; ++i) js << "\"" << params[i].name << "\"" << (i + 1 < n ? ", " : "");
  js << "], \"matrix\": [";
  for (size_t i = 0; i < n; ++i) {
    js << "[";
    for (size_t j = 0; j < n; ++j) js << C[i * n + j] << (j + 1 < n ? ", " : "");
    js << "]" << (i + 1 < n ? ", " : "");
  }
  js << "]},\n  \"tau_initial\": " << tau0 << ",\n  \"knot_spacing\": " << spacing
     << ",\n  \"iterations\": " << summary.iterations.size() - 1
     << ",\n  \"initial_cost\": " << summary.initial_cost
     << ",\n  \"final_cost\": " << summary.final_cost << ",\n  \"imu_samples_used\": " << used
     << ",\n  \"timing_s\": {\"read\": " << t_read - t_start
     << ", \"setup\": " << t_setup - t_read << ", \"solve\": " << t_solve - t_setup
     << ", \"covariance\": " << t_cov - t_solve << "}\n}\n";
  std::ofstream f(out);
  f << js.str();
  if (!f) {
    std::fprintf(stderr, "error: cannot write %s\n", out.c_str());
    return 1;
  }
  std::fprintf(stderr,
               "read %.3f s, set-up %.3f s, solve %.3f s (%d iterations, %s), covariance %.3f s\n",
               t_read - t_start, t_setup - t_read, t_solve - t_setup,
               int(summary.iterations.size()) - 1, solver.c_str(), t_cov - t_solve);
  return 0;
}
