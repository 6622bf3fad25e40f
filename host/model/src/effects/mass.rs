//! Mass model for joint elasticity: link masses and centres of mass, giving
//! the gravity torque on each joint,
//!
//! ```text
//! τ_j(q) = z_{j−1} · Σ_{l ≥ j} (c_l − p_{j−1}) × m_l g      g = (0, 0, −g0)
//! ```
//!
//! with z_{j−1}, p_{j−1} the axis and origin of joint j and c_l the centre of
//! mass of link l (the nominal chain, docs/model.md §1: frame l is the frame
//! after T_l and the link's fixed transform C_l, if any — for a robot
//! described by its maker's joint origins, the next joint's frame). A TOML
//! file gives one:
//!
//! ```text
//! [[link]]            # one table per link, base to flange
//! mass = 6.0          # kg
//! com = [-0.2, 0, 0]  # m, in the link's frame
//! ```

use serde::Deserialize;

use crate::geom::{add, cross, dot, mul_mv, sub, V3};
use crate::kinematics::LinkTransform;
use crate::robot::{ChainLink, DhLink};
use crate::{geom::Iso, Robot, MAX_JOINTS};

/// Link masses and centres of mass (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct MassModel {
    links: Vec<DhLink>,
    /// Per link: its fixed transform C_l, when not the identity.
    fixed: Vec<Option<Iso>>,
    /// Per link: (sin α, cos α) of its twist (for [`Self::link_transform`]).
    twist: Vec<(f64, f64)>,
    mass: Vec<f64>,
    com: Vec<V3>,
}

/// Why a mass model cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MassError {
    /// The TOML text is malformed.
    #[error("invalid mass model: {0}")]
    Toml(#[from] toml::de::Error),
    /// Wrong number of links or a negative mass.
    #[error("invalid mass model: {0}")]
    Invalid(String),
    /// The file cannot be read.
    #[error("cannot read the mass model {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    link: Vec<LinkMass>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkMass {
    mass: f64,
    com: [f64; 3],
}

impl MassModel {
    /// The model of the chain `links` with these masses and centres of mass.
    fn of_links(chain: &[ChainLink], mass: Vec<f64>, com: Vec<V3>) -> Self {
        let links: Vec<DhLink> = chain.iter().map(|l| l.dh).collect();
        let twist = links
            .iter()
            .map(|l| (l.alpha.sin(), l.alpha.cos()))
            .collect();
        Self {
            links,
            fixed: chain.iter().map(|l| l.fixed).collect(),
            twist,
            mass,
            com,
        }
    }

    /// No links: the catalogue of a session without a robot (a pose
    /// session, docs/model.md §7.9), whose joint-side effects do not apply.
    pub fn none() -> Self {
        Self::of_links(&[], Vec::new(), Vec::new())
    }

    /// From masses (kg) and centres of mass (m, link DH frames).
    pub fn new(robot: &Robot, mass: Vec<f64>, com: Vec<V3>) -> Result<Self, MassError> {
        let n = robot.dof();
        if mass.len() != n || com.len() != n {
            return Err(MassError::Invalid(format!(
                "{} links given but the robot has {n}",
                mass.len()
            )));
        }
        if let Some(m) = mass.iter().find(|m| !(m.is_finite() && **m >= 0.0)) {
            return Err(MassError::Invalid(format!("link mass {m} kg is not ≥ 0")));
        }
        Ok(Self::of_links(robot.chain(), mass, com))
    }

    /// A built-in estimate for the AUBO i5 (24 kg arm; masses and centres of
    /// mass guessed from its geometry: upper arm and forearm as uniform
    /// beams, wrist links as point masses on their axes).
    pub fn aubo_i5(robot: &Robot) -> Result<Self, MassError> {
        let mass = vec![5.0, 6.5, 3.0, 1.5, 1.5, 0.5];
        let com = vec![
            [0.0, 0.0, 0.02],
            [-0.204, 0.0, 0.06],
            [-0.188, 0.0, 0.01],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, -0.02],
        ];
        Self::new(robot, mass, com)
    }

    /// The built-in estimate for `robot` when there is one (AUBO i5), else
    /// a uniform 2 kg per link at the link's frame origin.
    pub fn for_robot(robot: &Robot) -> Self {
        if robot.name() == "aubo_i5" && robot.dof() == 6 {
            if let Ok(m) = Self::aubo_i5(robot) {
                return m;
            }
        }
        let n = robot.dof();
        Self::of_links(robot.chain(), vec![2.0; n], vec![[0.0; 3]; n])
    }

    /// Parse a TOML mass model for `robot`.
    pub fn from_toml_str(robot: &Robot, text: &str) -> Result<Self, MassError> {
        let f: File = toml::from_str(text)?;
        let (mass, com) = f.link.iter().map(|l| (l.mass, l.com)).unzip();
        Self::new(robot, mass, com)
    }

    /// Read a TOML mass model file.
    pub fn from_toml_file(robot: &Robot, path: &std::path::Path) -> Result<Self, MassError> {
        let text = crate::text::read_to_string(path).map_err(|source| MassError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(robot, &text)
    }

    /// Number of links.
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    /// Gravity torque τ_j(q) on every joint (N·m), gravity g0 along −z.
    pub fn gravity_torques(&self, q: &[f64], g0: f64) -> Vec<f64> {
        self.gravity_torques_array(q, g0)[..self.dof()].to_vec()
    }

    /// [`Self::gravity_torques`] without allocating (the same operations;
    /// entries beyond [`Self::dof`] zero): the effects evaluate it three
    /// times per IMU sample.
    ///
    /// # Panics
    /// With more links than [`MAX_JOINTS`] or fewer angles in `q` than links.
    pub fn gravity_torques_array(&self, q: &[f64], g0: f64) -> [f64; MAX_JOINTS] {
        let n = self.links.len();
        assert!(
            n <= MAX_JOINTS && q.len() >= n,
            "{n} links, {} angles",
            q.len()
        );
        let mut frames = [Iso::identity(); MAX_JOINTS + 1];
        for l in 0..n {
            frames[l + 1] = frames[l].compose(&self.link_transform(l, q[l]));
        }
        let mut centres = [[0.0; 3]; MAX_JOINTS];
        for l in 0..n {
            centres[l] = add(frames[l + 1].p, mul_mv(&frames[l + 1].r, self.com[l]));
        }
        let mut out = [0.0; MAX_JOINTS];
        for (j, o) in out.iter_mut().enumerate().take(n) {
            let axis = [frames[j].r[0][2], frames[j].r[1][2], frames[j].r[2][2]];
            let origin = frames[j].p;
            *o = (j..n)
                .map(|l| {
                    let force = [0.0, 0.0, -g0 * self.mass[l]];
                    dot(axis, cross(sub(centres[l], origin), force))
                })
                .sum();
        }
        out
    }

    /// The transform of link `l` at angle `q`, T_l(q)·C_l: the DH part
    /// with the twist's sine and cosine computed once ([`Self::twist`]).
    fn link_transform(&self, l: usize, q: f64) -> Iso {
        let dh = &self.links[l];
        let (st, ct) = crate::trig::sin_cos(q + dh.theta0);
        let (sa, ca) = self.twist[l];
        let t = Iso {
            r: [
                [ct, -(st * ca), st * sa],
                [st, ct * ca, -(ct * sa)],
                [0.0, sa, ca],
            ],
            p: [ct * dh.a, st * dh.a, dh.d],
        };
        match &self.fixed[l] {
            None => t,
            Some(c) => t.compose(c),
        }
    }
}

impl MassModel {
    /// Gravitational potential energy Σ m_l g0 z(c_l), J (for tests: τ = −∂V/∂q).
    pub fn potential_energy(&self, q: &[f64], g0: f64) -> f64 {
        let mut f = Iso::identity();
        let mut v = 0.0;
        for (l, (dh, &qi)) in self.links.iter().zip(q).enumerate() {
            let link = ChainLink {
                dh: *dh,
                fixed: self.fixed[l],
            };
            f = f.compose(&link.transform(qi));
            let c = add(f.p, mul_mv(&f.r, self.com[l]));
            v += self.mass[l] * g0 * c[2];
        }
        v
    }
}
