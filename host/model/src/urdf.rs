//! Robots from URDF: the serial chain of revolute joints from a base link to
//! a tip link, as a [`Robot`] (docs/model.md §1 with fixed transforms `C_i`, see
//! [`super::robot`]).
//!
//! URDF link frames follow `L_j = L_{j−1}·O_j·Rot(axis_j, q_j)` (`O_j` the
//! joint's `<origin>`). With `A_j` a fixed rotation taking z onto `axis_j`
//! (`A_j = I` when the axis is z), `Rot(axis_j, q) = A_j·Rz(q)·A_jᵀ`, so with
//! `P_j` the product of the origins from the previous revolute joint's child
//! link to joint j (fixed joints in between, then `O_j`) and `P_tip` those
//! from the last revolute joint to the tip:
//!
//! ```text
//! model base = L_base·P_1·A_1,   T_i(q) = Rz(q),
//! C_i = A_iᵀ·P_{i+1}·A_{i+1}  (i < n),   C_n = A_nᵀ·P_tip
//! ```
//!
//! The model's base frame is therefore joint 1's frame (its z axis is joint
//! 1's axis): gravity g (docs/model.md §2) is expressed in it. For the usual URDF,
//! where joint 1 turns about the base link's vertical z axis, it differs from
//! the base link by a translation and a rotation about the vertical, which
//! the IMU cannot see. The flange (IMU mount, `E_n`) frame is the tip link's
//! frame. The generalized error `E_i` sits on the fixed transform from joint
//! i to joint i+1 (after `C_i`), in joint i+1's axis-aligned frame.
//!
//! Limits: position from `<limit lower upper>` (continuous joints: ±π),
//! speed from `<limit velocity>`; URDF has no acceleration limit, so every
//! joint gets [`UrdfOptions::qdd_max`]. Joint noise, IMU noise, IMU mount and
//! priors are not in URDF: they take [`UrdfOptions`] (defaults: the AUBO i5
//! reference setup of docs/model.md §6). The estimated generalized errors are left
//! unset, to be found numerically (`crate::error_selection`).

use std::collections::HashMap;
use std::path::Path;

use super::geom::{self, Iso, M3, V3};
use super::robot::{
    Frames, ImuMount, JointDescription, NoiseDescription, Origin, Priors, Robot, RobotDescription,
    RobotError,
};

/// Why a URDF could not be turned into a robot.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("cannot read URDF {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Not well-formed XML.
    #[error("URDF is not well-formed XML: {0}")]
    Xml(#[from] roxmltree::Error),
    /// Well-formed, but not a URDF of the expected shape.
    #[error("URDF: {0}")]
    Invalid(String),
    /// The resulting description is rejected.
    #[error(transparent)]
    Robot(#[from] RobotError),
}

fn invalid(msg: impl Into<String>) -> UrdfError {
    UrdfError::Invalid(msg.into())
}

/// What URDF does not say (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfOptions {
    /// Base link (default: the tree's root link).
    pub base: Option<String>,
    /// Tip link, the flange (default: the only leaf link below the base).
    pub tip: Option<String>,
    /// Acceleration limit of every joint, rad/s² (default 100°/s², the
    /// paper's Table III value).
    pub qdd_max: f64,
    /// Joint sample noise σ of every joint, rad (default 1e-4).
    pub sigma_q: f64,
    /// IMU noise (default: docs/model.md §6).
    pub noise: NoiseDescription,
    /// IMU mount prior (default: docs/model.md §6).
    pub imu_mount: ImuMount,
    /// Prior σ (default: paper Table II).
    pub priors: Priors,
    /// Gravity magnitude g0, m/s² (default 9.81).
    pub gravity: f64,
}

impl Default for UrdfOptions {
    fn default() -> Self {
        let aubo = Robot::aubo_i5();
        let d = aubo.description();
        Self {
            base: None,
            tip: None,
            qdd_max: 100f64.to_radians(),
            sigma_q: 1e-4,
            noise: d.noise,
            imu_mount: d.imu_mount,
            priors: d.priors,
            gravity: d.gravity,
        }
    }
}

/// One URDF joint as written in the file.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfJoint {
    /// `name`.
    pub name: String,
    /// `type` (`revolute`, `continuous`, `fixed`, …).
    pub kind: String,
    /// Parent link.
    pub parent: String,
    /// Child link.
    pub child: String,
    /// `<origin>` (identity when absent).
    pub origin: Origin,
    /// `<axis xyz>`, unit length (URDF default (1, 0, 0)).
    pub axis: V3,
    /// `<limit lower upper>`, when given.
    pub position: Option<(f64, f64)>,
    /// `<limit velocity>`, when given.
    pub velocity: Option<f64>,
}

/// The chain a robot was built from: what a corrected URDF needs.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfChain {
    /// `<robot name>`.
    pub robot_name: String,
    /// Base link.
    pub base: String,
    /// Tip link.
    pub tip: String,
    /// The joints from base to tip (fixed ones included), in chain order.
    pub joints: Vec<UrdfJoint>,
    /// `A_i` of each revolute joint (z onto its axis), in chain order.
    pub align: Vec<M3>,
}

impl UrdfChain {
    /// The revolute (and continuous) joints, base to tip.
    pub fn revolute(&self) -> impl Iterator<Item = &UrdfJoint> {
        self.joints.iter().filter(|j| is_revolute(&j.kind))
    }
}

fn is_revolute(kind: &str) -> bool {
    kind == "revolute" || kind == "continuous"
}

fn numbers<const N: usize>(text: &str, what: &str) -> Result<[f64; N], UrdfError> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| invalid(format!("{what} = \"{text}\" is not {N} numbers")))?;
    let a: [f64; N] = v
        .try_into()
        .map_err(|_| invalid(format!("{what} = \"{text}\" is not {N} numbers")))?;
    if a.iter().any(|x| !x.is_finite()) {
        return Err(invalid(format!("{what} = \"{text}\" is not finite")));
    }
    Ok(a)
}

fn attr_f64(node: roxmltree::Node, name: &str, what: &str) -> Result<Option<f64>, UrdfError> {
    match node.attribute(name) {
        None => Ok(None),
        Some(t) => Ok(Some(numbers::<1>(t, &format!("{what} {name}"))?[0])),
    }
}

/// The deepest element nesting a URDF may have (real ones nest 4 or 5).
const MAX_DEPTH: usize = 256;
/// The most XML nodes a URDF may have.
const MAX_NODES: u32 = 1_000_000;

/// How deeply `text`'s elements nest, scanning no further than
/// [`MAX_DEPTH`] + 1 (the XML parser recurses per level: a deeper document
/// would overflow its stack). Comments, CDATA, processing instructions and
/// declarations are skipped; quoted attribute values may hold `>`.
fn nesting_depth(text: &str) -> usize {
    let b = text.as_bytes();
    let skip_to = |from: usize, end: &str| {
        text[from..]
            .find(end)
            .map_or(b.len(), |k| from + k + end.len())
    };
    let (mut i, mut depth, mut deepest) = (0, 0usize, 0usize);
    while let Some(k) = memchr_lt(&b[i..]) {
        i += k;
        let rest = &text[i..];
        if rest.starts_with("<!--") {
            i = skip_to(i, "-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(i, "]]>");
        } else if rest.starts_with("<?") {
            i = skip_to(i, "?>");
        } else if rest.starts_with("<!") {
            i = skip_to(i, ">");
        } else if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            i = skip_to(i, ">");
        } else {
            // A start tag: to its `>` outside quotes.
            let mut quote = None;
            let mut j = i + 1;
            while j < b.len() {
                match (quote, b[j]) {
                    (Some(q), c) if c == q => quote = None,
                    (None, c @ (b'"' | b'\'')) => quote = Some(c),
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            if b[j.min(b.len()) - 1] != b'/' {
                depth += 1;
                deepest = deepest.max(depth);
                if deepest > MAX_DEPTH {
                    break;
                }
            }
            i = (j + 1).min(b.len());
        }
    }
    deepest
}

/// The offset of the next `<` in `b`.
fn memchr_lt(b: &[u8]) -> Option<usize> {
    b.iter().position(|&c| c == b'<')
}

/// `text` as an XML document, refused when nested deeper than
/// [`MAX_DEPTH`] or holding more than [`MAX_NODES`] nodes.
fn parse_document(text: &str) -> Result<roxmltree::Document<'_>, UrdfError> {
    if nesting_depth(text) > MAX_DEPTH {
        return Err(invalid(format!(
            "elements nested more than {MAX_DEPTH} levels deep (a URDF nests 4 or 5)"
        )));
    }
    let opts = roxmltree::ParsingOptions {
        nodes_limit: MAX_NODES,
        ..roxmltree::ParsingOptions::default()
    };
    Ok(roxmltree::Document::parse_with_options(text, opts)?)
}

/// Every `<joint>` of a URDF document, and the `<robot name>`.
pub fn parse_joints(text: &str) -> Result<(String, Vec<UrdfJoint>), UrdfError> {
    let doc = parse_document(text)?;
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(invalid(format!(
            "the root element is <{}>, not <robot>",
            root.tag_name().name()
        )));
    }
    let robot_name = root.attribute("name").unwrap_or("urdf_robot").to_string();
    let mut joints = Vec::new();
    for j in root.children().filter(|n| n.has_tag_name("joint")) {
        let name = j
            .attribute("name")
            .ok_or_else(|| invalid("a <joint> has no name"))?
            .to_string();
        let kind = j
            .attribute("type")
            .ok_or_else(|| invalid(format!("joint `{name}` has no type")))?
            .to_string();
        let child_of = |tag: &str| -> Result<String, UrdfError> {
            j.children()
                .find(|n| n.has_tag_name(tag))
                .and_then(|n| n.attribute("link"))
                .map(str::to_string)
                .ok_or_else(|| invalid(format!("joint `{name}` has no <{tag} link=…>")))
        };
        let (parent, child) = (child_of("parent")?, child_of("child")?);
        let mut origin = Origin::IDENTITY;
        if let Some(o) = j.children().find(|n| n.has_tag_name("origin")) {
            if let Some(t) = o.attribute("xyz") {
                origin.xyz = numbers(t, &format!("joint `{name}` origin xyz"))?;
            }
            if let Some(t) = o.attribute("rpy") {
                origin.rpy = numbers(t, &format!("joint `{name}` origin rpy"))?;
            }
        }
        let mut axis = [1.0, 0.0, 0.0];
        if let Some(t) = j
            .children()
            .find(|n| n.has_tag_name("axis"))
            .and_then(|n| n.attribute("xyz"))
        {
            axis = numbers(t, &format!("joint `{name}` axis xyz"))?;
        }
        let norm = geom::dot(axis, axis).sqrt();
        if is_revolute(&kind) && norm < 1e-9 {
            return Err(invalid(format!("joint `{name}`: the axis is zero")));
        }
        if norm > 0.0 {
            axis = geom::scale(axis, 1.0 / norm);
        }
        let (mut position, mut velocity) = (None, None);
        if let Some(l) = j.children().find(|n| n.has_tag_name("limit")) {
            let what = format!("joint `{name}` limit");
            let lower = attr_f64(l, "lower", &what)?;
            let upper = attr_f64(l, "upper", &what)?;
            velocity = attr_f64(l, "velocity", &what)?;
            if kind == "revolute" {
                position = Some((lower.unwrap_or(0.0), upper.unwrap_or(0.0)));
            }
        }
        joints.push(UrdfJoint {
            name,
            kind,
            parent,
            child,
            origin,
            axis,
            position,
            velocity,
        });
    }
    Ok((robot_name, joints))
}

/// A rotation taking z onto the unit vector `a` (identity when `a` is z).
fn align_z(a: V3) -> M3 {
    let z = [0.0, 0.0, 1.0];
    if a == z {
        return geom::identity();
    }
    let c = a[2];
    if c < -1.0 + 1e-12 {
        return geom::rot_x(std::f64::consts::PI);
    }
    // Rodrigues about k = z × a: R = I + [v]× + [v]×² / (1 + c).
    let v = geom::cross(z, a);
    let h = [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]];
    let h2 = geom::mul_mm(&h, &h);
    let mut r = geom::identity();
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] += h[i][j] + h2[i][j] / (1.0 + c);
        }
    }
    r
}

/// Refuses joints that do not form a tree of links: a link that is the
/// child of two joints, or joints that loop back on themselves.
fn check_tree(joints: &[UrdfJoint]) -> Result<(), UrdfError> {
    let mut by_child: HashMap<&str, &UrdfJoint> = HashMap::new();
    for j in joints {
        if let Some(other) = by_child.insert(j.child.as_str(), j) {
            return Err(invalid(format!(
                "link `{}` is the child of joints `{}` and `{}`: the joints must form a tree",
                j.child, other.name, j.name
            )));
        }
    }
    // Each link's walk to its root, each link walked once: 1 on the current
    // walk, 2 known to reach a root.
    let mut state: HashMap<&str, u8> = HashMap::new();
    for j in joints {
        let mut path = Vec::new();
        let mut cur = j.child.as_str();
        loop {
            match state.get(cur) {
                Some(2) => break,
                Some(_) => {
                    return Err(invalid(format!(
                        "the joints loop back on themselves through link `{cur}`: they must form a tree"
                    )))
                }
                None => {}
            }
            state.insert(cur, 1);
            path.push(cur);
            match by_child.get(cur) {
                Some(parent) => cur = &parent.parent,
                None => break,
            }
        }
        for l in path {
            state.insert(l, 2);
        }
    }
    Ok(())
}

/// The joints from `base` to `tip`, in chain order.
fn chain_joints(
    joints: &[UrdfJoint],
    base: Option<&str>,
    tip: Option<&str>,
) -> Result<(String, String, Vec<UrdfJoint>), UrdfError> {
    check_tree(joints)?;
    let by_child: HashMap<&str, &UrdfJoint> =
        joints.iter().map(|j| (j.child.as_str(), j)).collect();
    let parents: std::collections::HashSet<&str> =
        joints.iter().map(|j| j.parent.as_str()).collect();
    let base = match base {
        Some(b) => b.to_string(),
        None => {
            let mut roots: Vec<&str> = parents
                .iter()
                .copied()
                .filter(|l| !by_child.contains_key(l))
                .collect();
            roots.sort();
            match roots.as_slice() {
                [r] => r.to_string(),
                _ => {
                    return Err(invalid(format!(
                        "cannot tell the base link: root links {roots:?}; name one with --base"
                    )))
                }
            }
        }
    };
    let tip = match tip {
        Some(t) => t.to_string(),
        None => {
            // Leaves whose path to the root passes through `base`.
            let mut leaves: Vec<&str> = joints
                .iter()
                .map(|j| j.child.as_str())
                .filter(|l| !parents.contains(l))
                .filter(|l| {
                    let mut cur = *l;
                    while let Some(j) = by_child.get(cur) {
                        if j.parent == base {
                            return true;
                        }
                        cur = &j.parent;
                    }
                    false
                })
                .collect();
            leaves.sort();
            match leaves.as_slice() {
                [l] => l.to_string(),
                _ => {
                    return Err(invalid(format!(
                        "cannot tell the tip link below `{base}`: leaf links {leaves:?}; name one with --tip"
                    )))
                }
            }
        }
    };
    let mut chain = Vec::new();
    let mut cur = tip.as_str();
    while cur != base {
        let j = by_child.get(cur).ok_or_else(|| {
            invalid(format!(
                "link `{tip}` is not below link `{base}` (no joint has child `{cur}`)"
            ))
        })?;
        if chain.len() > joints.len() {
            return Err(invalid("the joints form a cycle"));
        }
        chain.push((*j).clone());
        cur = &j.parent;
    }
    chain.reverse();
    Ok((base, tip, chain))
}

/// The robot of the chain from `opts.base` to `opts.tip` in URDF `text`, and
/// the chain (for writing a corrected URDF).
pub fn robot_from_urdf_str(
    text: &str,
    opts: &UrdfOptions,
) -> Result<(Robot, UrdfChain), UrdfError> {
    let (robot_name, joints) = parse_joints(text)?;
    let (base, tip, chain) = chain_joints(&joints, opts.base.as_deref(), opts.tip.as_deref())?;
    // P_j accumulation; C_i = A_iᵀ·P_{i+1}·A_{i+1}.
    let mut descs = Vec::new();
    let mut align = Vec::new();
    let mut pending = Iso::identity();
    let mut prev_align: Option<M3> = None;
    let mut base_to_model = Iso::identity();
    let push_c = |descs: &mut Vec<JointDescription>, a_prev: &M3, p: &Iso, a_next: &M3| {
        let c = Iso::rotation(geom::transpose(a_prev))
            .compose(p)
            .compose(&Iso::rotation(*a_next));
        if let Some(last) = descs.last_mut() {
            last.origin = Some(Origin::from_iso(&c));
        }
    };
    for j in &chain {
        let o = j.origin.to_iso();
        match j.kind.as_str() {
            "fixed" => pending = pending.compose(&o),
            "revolute" | "continuous" => {
                let p = pending.compose(&o);
                let a = align_z(j.axis);
                match &prev_align {
                    Some(ap) => push_c(&mut descs, ap, &p, &a),
                    // model base = L_base·P_1·A_1
                    None => base_to_model = p.compose(&Iso::rotation(a)),
                }
                let (q_min, q_max) = match j.position {
                    Some(r) => r,
                    None if j.kind == "continuous" => (-std::f64::consts::PI, std::f64::consts::PI),
                    None => {
                        return Err(invalid(format!(
                            "revolute joint `{}` has no <limit lower upper>",
                            j.name
                        )))
                    }
                };
                let qd_max = j.velocity.ok_or_else(|| {
                    invalid(format!("joint `{}` has no <limit velocity>", j.name))
                })?;
                descs.push(JointDescription {
                    theta0: 0.0,
                    d: 0.0,
                    a: 0.0,
                    alpha: 0.0,
                    q_min,
                    q_max,
                    qd_max,
                    qdd_max: opts.qdd_max,
                    sigma_q: opts.sigma_q,
                    origin: None,
                });
                align.push(a);
                prev_align = Some(a);
                pending = Iso::identity();
            }
            other => {
                return Err(invalid(format!(
                "joint `{}` is {other}: only revolute, continuous and fixed joints are supported",
                j.name
            )))
            }
        }
    }
    let Some(ap) = prev_align else {
        return Err(invalid(format!(
            "no revolute joint between `{base}` and `{tip}`"
        )));
    };
    push_c(&mut descs, &ap, &pending, &geom::identity());
    // Joints whose C_i is the identity to rounding keep no origin.
    for d in &mut descs {
        if let Some(o) = d.origin {
            if o.xyz.iter().chain(&o.rpy).all(|v| *v == 0.0) {
                d.origin = None;
            }
        }
    }
    let desc = RobotDescription {
        name: robot_name.clone(),
        gravity: opts.gravity,
        source: None,
        joint_names: chain
            .iter()
            .filter(|j| is_revolute(&j.kind))
            .map(|j| j.name.clone())
            .collect(),
        frames: Some(Frames {
            base: base.clone(),
            flange: tip.clone(),
            base_to_model: Origin::from_iso(&base_to_model),
        }),
        calibration_hash: None,
        joints: descs,
        noise: opts.noise,
        imu_mount: opts.imu_mount,
        priors: opts.priors,
        errors: None,
        imu_mounts: Default::default(),
    };
    let robot = Robot::new(desc)?;
    Ok((
        robot,
        UrdfChain {
            robot_name,
            base,
            tip,
            joints: chain,
            align,
        },
    ))
}

/// [`robot_from_urdf_str`] on a file.
pub fn robot_from_urdf_file(
    path: impl AsRef<Path>,
    opts: &UrdfOptions,
) -> Result<(Robot, UrdfChain), UrdfError> {
    let path = path.as_ref();
    let text = crate::text::read_to_string(path).map_err(|source| UrdfError::Io {
        path: path.display().to_string(),
        source,
    })?;
    robot_from_urdf_str(&text, opts)
}

/// The robot's nominal kinematics as a plain URDF (links and joints only):
/// the maker's base frame (`[frames] base`, else `base`), a fixed joint to
/// the model base (`base_to_model`), one revolute joint about z per joint
/// (named as `joint_names`, else `joint1`…; limits and speed from the
/// description) whose `<origin>` is the previous link's fixed part
/// `Rz(θ0)·Tz(d)·Tx(a)·Rx(α)·C`, and a fixed joint to the flange link
/// (`[frames] flange`, else `flange`). The URDF joint angle is the model's
/// q. Reading it back with [`robot_from_urdf_str`] gives the same flange
/// pose.
pub fn robot_to_urdf(robot: &Robot) -> String {
    use std::fmt::Write;
    let d = robot.description();
    let (base, flange, b2m) = match &d.frames {
        Some(f) => (f.base.clone(), f.flange.clone(), f.base_to_model),
        None => ("base".to_string(), "flange".to_string(), Origin::IDENTITY),
    };
    let name = |i: usize| {
        d.joint_names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("joint{}", i + 1))
    };
    // Frame i of the model (after joint i); a name no maker uses.
    let link = |i: usize| format!("robimu_frame{i}");
    let origin = |o: &Origin| {
        format!(
            r#"<origin xyz="{:?} {:?} {:?}" rpy="{:?} {:?} {:?}"/>"#,
            o.xyz[0], o.xyz[1], o.xyz[2], o.rpy[0], o.rpy[1], o.rpy[2]
        )
    };
    let mut out = String::new();
    let _ = writeln!(out, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(
        out,
        "<!-- robimu nominal description of `{}` (links and joints only){} -->",
        d.name,
        d.source
            .as_ref()
            .map(|s| format!("; source: {}", s.replace("--", "- -")))
            .unwrap_or_default()
    );
    let _ = writeln!(out, r#"<robot name="{}">"#, d.name);
    let _ = writeln!(out, r#"  <link name="{base}"/>"#);
    for i in 0..=robot.dof() {
        let _ = writeln!(out, r#"  <link name="{}"/>"#, link(i));
    }
    let _ = writeln!(out, r#"  <link name="{flange}"/>"#);
    let _ = writeln!(
        out,
        r#"  <joint name="{base}-model_base" type="fixed"><parent link="{base}"/><child link="{}"/>{}</joint>"#,
        link(0),
        origin(&b2m)
    );
    let mut prev = Origin::IDENTITY;
    for (i, (c, l)) in robot.chain().iter().zip(robot.limits()).enumerate() {
        let _ = writeln!(
            out,
            r#"  <joint name="{}" type="revolute"><parent link="{}"/><child link="{}"/>{}<axis xyz="0 0 1"/><limit lower="{:?}" upper="{:?}" velocity="{:?}" effort="0"/></joint>"#,
            name(i),
            link(i),
            link(i + 1),
            origin(&prev),
            l.q_min,
            l.q_max,
            l.qd_max
        );
        let mut dh = c.dh;
        dh.theta0 = 0.0;
        let fixed = Iso::rotation(geom::rot_z(c.dh.theta0))
            .compose(&crate::kinematics::link_transform(&dh, 0.0))
            .compose(&c.fixed.unwrap_or_else(Iso::identity));
        prev = Origin::from_iso(&fixed);
    }
    let _ = writeln!(
        out,
        r#"  <joint name="{}-{flange}" type="fixed"><parent link="{}"/><child link="{flange}"/>{}</joint>"#,
        link(robot.dof()),
        link(robot.dof()),
        origin(&prev)
    );
    out.push_str("</robot>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::{matrix_rpy, rpy_matrix};

    #[test]
    fn align_z_takes_z_onto_the_axis() {
        for a in [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.48, -0.6, 0.64],
        ] {
            let r = align_z(a);
            let z = geom::col(&r, 2);
            for k in 0..3 {
                assert!((z[k] - a[k]).abs() < 1e-15, "{a:?}: {z:?}");
            }
            let rrt = geom::mul_mm(&r, &geom::transpose(&r));
            for i in 0..3 {
                for j in 0..3 {
                    let id = if i == j { 1.0 } else { 0.0 };
                    assert!((rrt[i][j] - id).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn rpy_round_trips_including_gimbal_lock() {
        use std::f64::consts::FRAC_PI_2;
        for rpy in [
            [0.3, -0.2, 2.9],
            [-FRAC_PI_2, -FRAC_PI_2, 0.0],
            [1.1, FRAC_PI_2, -0.4],
            [3.1, 1e-7 - FRAC_PI_2, 0.2],
        ] {
            let m = rpy_matrix(rpy);
            let back = rpy_matrix(matrix_rpy(&m));
            for i in 0..3 {
                for j in 0..3 {
                    assert!((m[i][j] - back[i][j]).abs() < 1e-14, "{rpy:?}");
                }
            }
        }
    }

    #[test]
    fn bad_urdf_is_a_clear_error() {
        let cases = [
            ("<robot", "well-formed"),
            ("<model/>", "not <robot>"),
            (
                r#"<robot name="r"><joint name="j" type="prismatic"><parent link="a"/><child link="b"/></joint></robot>"#,
                "prismatic",
            ),
            (
                r#"<robot name="r"><joint name="j" type="revolute"><parent link="a"/><child link="b"/><limit lower="-1" upper="1"/></joint></robot>"#,
                "velocity",
            ),
            (
                r#"<robot name="r"><joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 x 0"/></joint></robot>"#,
                "not 3 numbers",
            ),
        ];
        for (text, needle) in cases {
            let e = robot_from_urdf_str(text, &UrdfOptions::default())
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }

    /// Issue 41: hostile URDFs are refused, not a stack overflow or a hang.
    #[test]
    fn deep_or_looping_urdf_is_refused() {
        let joint = |name: &str, parent: &str, child: &str| {
            format!(
                r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/></joint>"#
            )
        };
        let deep = format!(
            r#"<robot name="r">{}{}</robot>"#,
            "<a>".repeat(100_000),
            "</a>".repeat(100_000)
        );
        let looped = format!(
            r#"<robot name="r">{}{}{}</robot>"#,
            joint("j0", "base", "l1"),
            joint("j1", "l2", "l3"),
            joint("j2", "l3", "l2")
        );
        let two_parents = format!(
            r#"<robot name="r">{}{}</robot>"#,
            joint("j0", "base", "l1"),
            joint("j1", "l0", "l1")
        );
        // Comments, quoted `>` and self-closing tags do not count as depth.
        let fine = format!(
            r#"<?xml version="1.0"?><!-- <a><a> --><robot name="r"><link name="x>y"/>{}</robot>"#,
            joint("j0", "base", "l1")
        );
        assert_eq!(nesting_depth(&fine), 2);
        robot_from_urdf_str(&fine, &UrdfOptions::default()).unwrap();
        for (text, needle) in [
            (deep, "nested more than 256 levels deep"),
            (looped, "the joints loop back on themselves through link `l"),
            (
                two_parents,
                "link `l1` is the child of joints `j0` and `j1`",
            ),
        ] {
            let e = robot_from_urdf_str(&text, &UrdfOptions::default())
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }
}
