//! The calibrated robot as a robot description: TOML (the format of
//! [`robimu_model::robot`]) or a corrected URDF.
//!
//! The calibrated chain is `T_i(q)·C_i·E_i` with the estimated `E_i`
//! (docs/model.md §1). Both exports fold each `E_i`, i < n, into the fixed
//! transform after joint i, so that the exported robot with all generalized
//! errors zero has the calibrated kinematics:
//!
//! ```text
//! C'_i = C_i·E_i   (i < n),   C'_n = C_n,   IMU mount position = (ε_n1, ε_n2, ε_n3)
//! ```
//!
//! In a URDF this changes the `<origin>` of revolute joint i+1 only:
//! `O'_{i+1} = O_{i+1}·A_{i+1}·E_i·A_{i+1}ᵀ` ([`robimu_model::urdf`]); joint 1,
//! fixed joints and all names stay as they were. The IMU mount is added as a
//! fixed joint `imu_joint` from the tip link to a new link `imu_link` (the
//! IMU frame: origin at the IMU, axes those of the tip link).

use robimu_model::geom::{self, Iso};
use robimu_model::kinematics::error_transform;
use robimu_model::robot::{ErrorsDescription, Origin, RobotDescription};
use robimu_model::urdf::{self, UrdfError};
use robimu_model::{ModelParams, Robot};

use super::ExportError;

/// The calibrated robot's description: `C'_i = C_i·E_i` for i < n, the IMU
/// mount prior centred on the estimated mount (position ε_n1..3, sensor
/// rotations r_a, r_ω), the same estimated-error set, limits, noise and priors.
pub(crate) fn corrected_description(robot: &Robot, params: &ModelParams) -> RobotDescription {
    let mut desc = robot.description().clone();
    let n = desc.joints.len();
    for (i, (j, link)) in desc.joints.iter_mut().zip(robot.chain()).enumerate() {
        if i + 1 == n {
            continue;
        }
        let c = link.fixed.unwrap_or_else(Iso::identity);
        let corrected = c.compose(&error_transform(&params.eps[i]));
        j.origin = Some(Origin::from_iso(&corrected));
    }
    let e = &params.eps[n - 1];
    desc.imu_mount.position = [e[0], e[1], e[2]];
    desc.imu_mount.r_a = params.accel.r;
    desc.imu_mount.r_w = params.gyro.r;
    desc.errors = Some(ErrorsDescription {
        estimated: robot.estimated_errors().to_vec(),
    });
    desc
}

/// The calibrated robot as robot TOML (readable by `Robot::from_toml_file`).
pub fn corrected_toml(robot: &Robot, params: &ModelParams) -> Result<String, ExportError> {
    let desc = corrected_description(robot, params);
    let body = toml::to_string(&desc)?;
    Ok(format!(
        "# Calibrated robot written by robimu (SI units: m, rad, s).\n\
         # Each joint's `origin` is the fixed transform C_i·E_i after its DH part\n\
         # (the estimated generalized errors folded in); imu_mount is the estimated\n\
         # IMU mount. With all generalized errors zero this robot has the\n\
         # calibrated kinematics.\n{body}"
    ))
}

fn fmt3(v: [f64; 3]) -> String {
    format!("{:?} {:?} {:?}", v[0], v[1], v[2])
}

fn origin_element(o: &Origin) -> String {
    format!(r#"<origin xyz="{}" rpy="{}"/>"#, fmt3(o.xyz), fmt3(o.rpy))
}

/// The corrected URDF: `text` (the URDF the robot was imported from, with
/// the same base and tip in `opts`) with the origins of revolute joints
/// 2..n corrected and an `imu_link` added (see the module doc).
pub fn corrected_urdf(
    text: &str,
    opts: &urdf::UrdfOptions,
    params: &ModelParams,
) -> Result<String, ExportError> {
    let (robot, chain) = urdf::robot_from_urdf_str(text, opts)?;
    let n = robot.dof();
    if params.eps.len() != n {
        return Err(UrdfError::Invalid(format!(
            "the chain {} → {} has {n} revolute joints but the calibration has {}",
            chain.base,
            chain.tip,
            params.eps.len()
        ))
        .into());
    }
    let doc = roxmltree::Document::parse(text).map_err(UrdfError::from)?;
    let root = doc.root_element();
    // (byte range to replace, replacement), applied from the end.
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    for (i, j) in chain.revolute().enumerate().skip(1) {
        let a = chain.align[i];
        let d = Iso::rotation(a)
            .compose(&error_transform(&params.eps[i - 1]))
            .compose(&Iso::rotation(geom::transpose(&a)));
        let corrected = Origin::from_iso(&j.origin.to_iso().compose(&d));
        let node = root
            .children()
            .find(|c| c.has_tag_name("joint") && c.attribute("name") == Some(j.name.as_str()))
            .expect("the chain's joints come from this document");
        let elem = origin_element(&corrected);
        match node.children().find(|c| c.has_tag_name("origin")) {
            Some(o) => edits.push((o.range(), elem)),
            None => {
                let start = node.range().start;
                let end = start + text[start..].find('>').expect("a start tag ends") + 1;
                edits.push((end..end, format!("\n    {elem}")));
            }
        }
    }
    let names: std::collections::HashSet<&str> = root
        .descendants()
        .filter_map(|c| c.attribute("name"))
        .collect();
    let (mut link, mut joint) = ("imu_link".to_string(), "imu_joint".to_string());
    while names.contains(link.as_str()) || names.contains(joint.as_str()) {
        link.insert_str(0, "robimu_");
        joint.insert_str(0, "robimu_");
    }
    let e = &params.eps[n - 1];
    let close = root.range().end - "</robot>".len();
    if !text[close..root.range().end].starts_with("</robot>") {
        return Err(UrdfError::Invalid("<robot> has no closing tag".into()).into());
    }
    edits.push((
        close..close,
        format!(
            "  <!-- robimu: the calibrated IMU frame (origin at the IMU, axes of `{tip}`) -->\n  \
             <link name=\"{link}\"/>\n  \
             <joint name=\"{joint}\" type=\"fixed\">\n    \
             <parent link=\"{tip}\"/>\n    <child link=\"{link}\"/>\n    \
             <origin xyz=\"{xyz}\" rpy=\"0 0 0\"/>\n  </joint>\n",
            tip = chain.tip,
            xyz = fmt3([e[0], e[1], e[2]]),
        ),
    ));
    edits.sort_by_key(|(r, _)| std::cmp::Reverse(r.start));
    let mut out = text.to_string();
    for (range, s) in edits {
        out.replace_range(range, &s);
    }
    let header = "<!-- Corrected by robimu: revolute joint origins carry the calibrated generalized errors. -->\n";
    match out.find("?>") {
        Some(p) if out.starts_with("<?xml") => out.insert_str(p + 2, &format!("\n{header}")),
        _ => out.insert_str(0, header),
    }
    Ok(out)
}
