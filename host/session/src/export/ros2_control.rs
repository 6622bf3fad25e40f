//! Joint zero offsets for ros2_control: one `SimpleTransmission` per joint
//! (`transmission_interface/SimpleTransmission`, whose position mapping is
//! joint = actuator / mechanical_reduction + offset), inside a
//! `<ros2_control>` tag to merge into the robot's own. The offsets come
//! from the workflow that fits them (`robimu_workflows::joint_offsets`).

use std::fmt::Write;

/// The transmissions' XML for the joints `names` (chain order) with
/// `offsets` (rad); `comment` (lines) heads the file. `robot` names the
/// `<robot>` and the `<ros2_control>` tag.
pub fn ros2_control_offsets(
    robot: &str,
    names: &[String],
    offsets: &[f64],
    comment: &[String],
) -> String {
    let mut out = String::from("<?xml version=\"1.0\"?>\n<!--\n");
    for line in comment {
        // "--" may not appear inside an XML comment
        let _ = writeln!(out, "  {}", line.replace("--", "- -"));
    }
    out.push_str("-->\n");
    let robot = escape(robot);
    let _ = writeln!(out, "<robot name=\"{robot}\">");
    let _ = writeln!(
        out,
        "  <ros2_control name=\"{robot}_joint_offsets\" type=\"system\">"
    );
    for (name, offset) in names.iter().zip(offsets) {
        let name = escape(name);
        let _ = writeln!(out, "    <transmission name=\"{name}_transmission\">");
        let _ = writeln!(
            out,
            "      <plugin>transmission_interface/SimpleTransmission</plugin>"
        );
        let _ = writeln!(
            out,
            "      <actuator name=\"{name}_actuator\" role=\"actuator1\"/>"
        );
        let _ = writeln!(out, "      <joint name=\"{name}\" role=\"joint1\">");
        let _ = writeln!(
            out,
            "        <mechanical_reduction>1.0</mechanical_reduction>"
        );
        let _ = writeln!(out, "        <offset>{offset:e}</offset>");
        let _ = writeln!(out, "      </joint>");
        let _ = writeln!(out, "    </transmission>");
    }
    out.push_str("  </ros2_control>\n</robot>\n");
    out
}

/// `s` as XML attribute text.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Read back by an XML parser (roxmltree): every joint's transmission
    /// with its offset to the bit, names escaped, the comment well formed.
    #[test]
    fn the_offsets_read_back() {
        let names = vec!["shoulder_pan_joint".to_string(), "a\"<&b".to_string()];
        let offsets = [1.234_567_890_123_456_7e-3, -0.1];
        let text = ros2_control_offsets("ur5e", &names, &offsets, &["a -- b".into()]);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let joints: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("joint"))
            .collect();
        assert_eq!(joints.len(), 2);
        for ((j, name), offset) in joints.iter().zip(&names).zip(offsets) {
            assert_eq!(j.attribute("name"), Some(name.as_str()));
            let o = j.children().find(|c| c.has_tag_name("offset")).unwrap();
            assert_eq!(o.text().unwrap().parse::<f64>().unwrap(), offset);
            let plugin = j
                .parent()
                .unwrap()
                .children()
                .find(|c| c.has_tag_name("plugin"));
            assert_eq!(
                plugin.unwrap().text(),
                Some("transmission_interface/SimpleTransmission")
            );
        }
    }
}
