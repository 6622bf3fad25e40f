//! Joint elasticity: each joint deflects in proportion to the gravity torque
//! it carries (a torsional spring of compliance c_j),
//!
//! ```text
//! q_j = q_enc,j + c_j τ_j(q)      δq̇_j = c_j τ̇_j,  δq̈_j = c_j τ̈_j
//! z ≈ h + Σ_j c_j (∂z/∂q_j τ_j + ∂z/∂q̇_j τ̇_j + ∂z/∂q̈_j τ̈_j)
//! ```
//!
//! τ_j(q) from a [`MassModel`] (the built-in AUBO i5 estimate, or a TOML file
//! via `--mass-model`); τ̇, τ̈ by central differences (±1 ms) of τ along the
//! trajectory's Taylor expansion. Only joints the mass model ever loads get a
//! parameter (not a vertical base joint, not a wrist joint carrying only
//! a mass on its axis). c in rad/(N·m), displayed in °/(kN·m).
//! `simulate --effect joint_elasticity=M` (M in °/(kN·m)) injects c = M for
//! every loaded joint. A wrong mass model scales the estimate by the
//! torque's error (the effect is still detected; c·m is what the data sees).

use super::{shifted, Effect, EffectParam, ExactContext, MassModel, SampleContext, TIME_STEP};
use crate::{JointState, ParamLayout, MAX_JOINTS};

/// See the module doc.
pub(crate) struct JointElasticity {
    mass: MassModel,
    g0: f64,
    /// Joints with a parameter.
    loaded: Vec<usize>,
}

/// °/(kN·m) per rad/(N·m).
const DISPLAY: f64 = 180.0 / std::f64::consts::PI * 1e3;

/// Gravity torques and their first two time derivatives at a joint state.
fn torques(mass: &MassModel, g0: f64, js: &JointState) -> [[f64; MAX_JOINTS]; 3] {
    let n = mass.dof();
    let h = TIME_STEP;
    let t0 = mass.gravity_torques_array(&js.q[..n], g0);
    let tp = mass.gravity_torques_array(&shifted(js, h).q[..n], g0);
    let tm = mass.gravity_torques_array(&shifted(js, -h).q[..n], g0);
    let mut d1 = [0.0; MAX_JOINTS];
    let mut d2 = [0.0; MAX_JOINTS];
    for j in 0..n {
        d1[j] = (tp[j] - tm[j]) / (2.0 * h);
        d2[j] = (tp[j] - 2.0 * t0[j] + tm[j]) / (h * h);
    }
    [t0, d1, d2]
}

impl JointElasticity {
    /// With mass model `mass` and gravity `g0`.
    pub fn new(mass: MassModel, g0: f64) -> Self {
        let n = mass.dof();
        // a joint is loaded if some pose puts more than 0.1 N·m on it
        let mut max = vec![0.0f64; n];
        for k in 0..64 {
            let q: Vec<f64> = (0..n)
                .map(|j| 1.5 * ((k as f64 + 1.0) * (j as f64 + 1.3) * 0.77).sin())
                .collect();
            for (m, t) in max.iter_mut().zip(mass.gravity_torques(&q, g0)) {
                *m = m.max(t.abs());
            }
        }
        let loaded = (0..n).filter(|&j| max[j] > 0.1).collect();
        Self { mass, g0, loaded }
    }
}

impl Effect for JointElasticity {
    fn name(&self) -> &'static str {
        "joint_elasticity"
    }
    fn description(&self) -> &'static str {
        "joint elasticity: deflection c_j × gravity torque (deg/kN·m)"
    }
    fn params(&self) -> Vec<EffectParam> {
        self.loaded
            .iter()
            .map(|j| EffectParam {
                name: format!("joint_elasticity.c_{}", j + 1),
                unit: "rad/(N*m)",
                display: ("deg/(kN*m)", DISPLAY),
                prior_sigma: 1e-3,
            })
            .collect()
    }
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        let [t, d1, d2] = torques(&self.mass, self.g0, ctx.js);
        for (a, &j) in self.loaded.iter().enumerate() {
            cols[a] = ctx.through_joints(j, t[j], d1[j], d2[j]);
        }
    }
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], _: &ParamLayout) -> [f64; 6] {
        let mut js = (ctx.trajectory)(ctx.t + ctx.tau);
        let [t, d1, d2] = torques(&self.mass, self.g0, &js);
        for (a, &j) in self.loaded.iter().enumerate() {
            js.q[j] += theta[a] * t[j];
            js.qd[j] += theta[a] * d1[j];
            js.qdd[j] += theta[a] * d2[j];
        }
        ctx.model.predict(&js)
    }
    fn magnitude_unit(&self) -> &'static str {
        "deg/(kN*m)"
    }
    fn injection(&self, magnitude: f64) -> Vec<f64> {
        vec![magnitude / DISPLAY; self.loaded.len()]
    }
}
