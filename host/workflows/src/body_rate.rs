//! The angular velocity of the IMU frame from the joint positions and
//! speeds alone (docs/model.md §1.3, §1.5): ω_n = Σ_i z_{i−1} q̇_i in the
//! base frame, z_{i−1} the axis of joint i (the z axis of the real frame
//! i − 1, after E_{i−1}), and ω = R_nᵀ ω_n in the IMU frame.
//!
//! The rotation part of the chain only: the check's gyroscope scale (§7.8)
//! and the τ search's predicted rate (§6.5) need no position, velocity or
//! acceleration of the frames, nor the specific force. The operations are those of
//! [`MeasurementModel`]'s chain walk and gyroscope output, in their order,
//! so that ω equals the ω of [`MeasurementModel::inertial`] and the reading
//! ω̃ the gyroscope's of [`MeasurementModel::predict`] bit for bit (tested).
//! Generic over [`Scalar`]: with [`F64x4`] four joint states at once, each
//! lane the bits of the `f64` call ([`robimu_model::lanes`]).

use robimu_model::geom::{self, M3, V3};
use robimu_model::jet::Scalar;
use robimu_model::lanes::F64x4;
use robimu_model::{MeasurementModel, Robot};

/// One link's constant rotations.
#[derive(Debug, Clone)]
struct LinkRotation {
    theta0: f64,
    ca: f64,
    sa: f64,
    /// The fixed transform C_i's rotation (§1.6).
    fixed: Option<M3>,
    /// The error transform E_i's rotation, when not the identity.
    error: Option<M3>,
}

/// The chain's rotations and the gyroscope's intrinsics at the parameters
/// of a measurement model.
#[derive(Debug, Clone)]
pub(crate) struct BodyRate {
    links: Vec<LinkRotation>,
    /// K Γ R of the gyroscope (eq. (6)), as the model forms it.
    gyro_m: M3,
    /// Its bias.
    gyro_b: V3,
}

impl BodyRate {
    /// The rotations of `robot` at the errors ε of `model`'s x.
    pub fn new(robot: &Robot, model: &MeasurementModel) -> Self {
        let links = robot
            .chain()
            .iter()
            .zip(&model.params().eps)
            .map(|(link, e)| {
                let dh = &link.dh;
                let identity = e[3] == 0.0 && e[4] == 0.0 && e[5] == 0.0;
                LinkRotation {
                    theta0: dh.theta0,
                    ca: dh.alpha.cos(),
                    sa: dh.alpha.sin(),
                    fixed: link.fixed.map(|c| c.r),
                    error: (!identity).then(|| {
                        let ryz = geom::mul_mm(&geom::rot_y(e[3]), &geom::rot_z(e[4]));
                        geom::mul_mm(&ryz, &geom::rot_x(e[5]))
                    }),
                }
            })
            .collect();
        let g = &model.params().gyro;
        let k = [[g.k[0], 0.0, 0.0], [0.0, g.k[1], 0.0], [0.0, 0.0, g.k[2]]];
        let kg = geom::mul_mm(&k, &g.gamma_matrix());
        Self {
            links,
            gyro_m: geom::mul_mm(&kg, &g.rotation()),
            gyro_b: g.b,
        }
    }

    /// The gyroscope's reading ω̃ = K Γ R ω + b (eq. (6)): the last three
    /// entries of [`MeasurementModel::predict`].
    #[inline(always)]
    pub fn gyro<S: Scalar>(&self, q: &[S], qd: &[S]) -> V3<S> {
        geom::add(
            geom::mul_mv(&cst_m(&self.gyro_m), self.imu(q, qd)),
            self.gyro_b.map(S::cst),
        )
    }

    /// ω in the IMU frame at joint positions `q` and speeds `qd` (one per
    /// joint).
    #[inline(always)]
    pub fn imu<S: Scalar>(&self, q: &[S], qd: &[S]) -> V3<S> {
        let (w, r) = self.base(q, qd);
        geom::mul_mtv(&r, w)
    }

    /// ω_n in the base frame and the IMU frame's rotation R_n.
    #[inline(always)]
    pub fn base<S: Scalar>(&self, q: &[S], qd: &[S]) -> (V3<S>, M3<S>) {
        let zero = S::cst(0.0);
        let mut w = [zero; 3];
        let mut r = geom::identity();
        for ((l, &qi), &qdi) in self.links.iter().zip(q).zip(qd) {
            w = geom::add(w, geom::scale(geom::col(&r, 2), qdi));
            let (st, ct) = (qi + l.theta0).sin_cos();
            let mz = [
                [ct, -st * l.ca, st * l.sa],
                [st, ct * l.ca, -ct * l.sa],
                [zero, S::cst(l.sa), S::cst(l.ca)],
            ];
            let mut rg = geom::mul_mm(&r, &mz);
            if let Some(cr) = &l.fixed {
                rg = geom::mul_mm(&rg, &cst_m(cr));
            }
            r = match &l.error {
                Some(e) => geom::mul_mm(&rg, &cst_m(e)),
                None => rg,
            };
        }
        (w, r)
    }

    /// [`Self::imu`] of four joint states, one per lane (`q[j]`, `qd[j]`
    /// joint j's positions and speeds; each lane the bits of the `f64` call).
    pub fn imu_x4(&self, q: &[F64x4], qd: &[F64x4]) -> [V3; 4] {
        self.x4(q, qd, false)
    }

    /// [`Self::gyro`] of four joint states, as [`Self::imu_x4`].
    pub fn gyro_x4(&self, q: &[F64x4], qd: &[F64x4]) -> [V3; 4] {
        self.x4(q, qd, true)
    }

    /// ω̃ (`gyro`) or ω of the lanes, compiled for AVX2 where the CPU has it
    /// (as `MeasurementModel::predict_x4`), split back into lanes.
    fn x4(&self, q: &[F64x4], qd: &[F64x4], gyro: bool) -> [V3; 4] {
        // as the f64 calls: the links paired with the given joints
        let n = self.links.len().min(q.len()).min(qd.len());
        let (q, qd) = (&q[..n], &qd[..n]);
        #[inline(always)]
        fn lanes(r: &BodyRate, q: &[F64x4], qd: &[F64x4], gyro: bool) -> V3<F64x4> {
            if gyro {
                r.gyro(q, qd)
            } else {
                r.imu(q, qd)
            }
        }
        let w = 'w: {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx,avx2")]
                fn avx2(r: &BodyRate, q: &[F64x4], qd: &[F64x4], gyro: bool) -> V3<F64x4> {
                    lanes(r, q, qd, gyro)
                }
                if robimu_model::lanes::has_avx2() {
                    // SAFETY: the CPU has AVX and AVX2 (checked just above).
                    break 'w unsafe { avx2(self, q, qd, gyro) };
                }
            }
            lanes(self, q, qd, gyro)
        };
        std::array::from_fn(|l| [w[0].lane(l), w[1].lane(l), w[2].lane(l)])
    }
}

/// A constant matrix in the scalar type `S`.
#[inline(always)]
fn cst_m<S: Scalar>(m: &M3) -> M3<S> {
    m.map(|row| row.map(S::cst))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use robimu_model::{JointState, ParamLayout};

    /// At random joint states, at the nominal and at random parameters
    /// (errors ε on every link, the gyroscope's intrinsics) ω and the
    /// gyroscope's reading equal the model's bit for bit, for the AUBO i5
    /// and a URDF robot with general axes and fixed joints; four of them at
    /// once in the lanes of `imu_x4`/`gyro_x4` give the same bits.
    #[test]
    fn equals_the_models_rate_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        // general joint axes, fixed joints between the revolute ones
        let urdf = include_str!("../../cli/tests/fixtures/axes_3r.urdf");
        let opts = robimu_model::urdf::UrdfOptions {
            base: Some("world".into()),
            tip: Some("tool0".into()),
            ..Default::default()
        };
        let (axes, _) = robimu_model::urdf::robot_from_urdf_str(urdf, &opts).unwrap();
        assert!(axes.chain().iter().any(|l| l.fixed.is_some()));
        let robots = [Robot::aubo_i5(), axes];
        for robot in robots {
            let layout = ParamLayout::new(&robot);
            let nominal = layout.nominal();
            let mut x = nominal.clone();
            for (k, s) in layout.specs().iter().enumerate() {
                x[k] += s.sigma * rng.random_range(-2.0..2.0);
            }
            let n = robot.dof();
            for x in [&nominal, &x] {
                let model = MeasurementModel::new(&robot, &layout, x).unwrap();
                let rate = BodyRate::new(&robot, &model);
                let mut states = Vec::new();
                for _ in 0..200 {
                    let q: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
                    let qd: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
                    let qdd: Vec<f64> = (0..n).map(|_| rng.random_range(-5.0..5.0)).collect();
                    let js = JointState::from_slices(&q, &qd, &qdd, &qdd);
                    assert_eq!(rate.imu(&q, &qd), model.inertial(&js).1);
                    let z = model.predict(&js);
                    assert_eq!(&z[3..], &rate.gyro(&q, &qd)[..]);
                    states.push((q, qd));
                }
                // four lanes: each the bits of its f64 call
                for four in states.chunks_exact(4) {
                    // lane l of joint j: state l's value
                    let lanes = |speed: bool| -> Vec<F64x4> {
                        (0..n)
                            .map(|j| {
                                F64x4(std::array::from_fn(|l| {
                                    if speed {
                                        four[l].1[j]
                                    } else {
                                        four[l].0[j]
                                    }
                                }))
                            })
                            .collect()
                    };
                    let (q4, qd4) = (lanes(false), lanes(true));
                    let (w4, g4) = (rate.imu_x4(&q4, &qd4), rate.gyro_x4(&q4, &qd4));
                    for (l, (q, qd)) in four.iter().enumerate() {
                        assert_eq!(w4[l], rate.imu(q, qd));
                        assert_eq!(g4[l], rate.gyro(q, qd));
                    }
                }
            }
        }
    }
}
