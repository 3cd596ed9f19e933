//! Where a scene error is: serde's message turned into the dotted key it is about, what was
//! found and what was expected, and the line of that key in the file.

/// serde_path_to_error writes `bodies[0].material`; scene keys are `bodies.0.material`.
pub(super) fn scene_path(p: &str) -> String {
    let p = p.replace('[', ".").replace(']', "");
    if p == "." {
        String::new()
    } else {
        p
    }
}

/// The value at a dotted key path (`bodies.0.material`), if present.
pub(super) fn value_at<'a>(root: &'a toml::Value, key: &str) -> Option<&'a toml::Value> {
    let mut v = root;
    for part in key.split('.').filter(|p| !p.is_empty()) {
        v = match v {
            toml::Value::Table(t) => t.get(part)?,
            toml::Value::Array(a) => a.get(part.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(v)
}

/// serde's description of a value (`serde::de::Unexpected`), as it appears in its messages.
fn unexpected(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => format!("string {s:?}"),
        toml::Value::Integer(i) => format!("integer `{i}`"),
        toml::Value::Float(f) => format!("floating point `{}`", serde_float(*f)),
        toml::Value::Boolean(b) => format!("boolean `{b}`"),
        toml::Value::Array(_) => "sequence".into(),
        toml::Value::Table(_) => "map".into(),
        toml::Value::Datetime(d) => format!("{d}"),
    }
}

fn serde_float(f: f64) -> String {
    // serde prints floats with a trailing ".0" when integral (its `WithDecimalPoint`).
    let s = f.to_string();
    if f.is_finite() && !s.contains(['.', 'e', 'E']) {
        format!("{s}.0")
    } else {
        s
    }
}

/// serde_path_to_error stops at the table of an internally tagged enum (`material`, `shape`,
/// `friction`) and at the table holding a missing field; this finds the key inside it that
/// the message is about, so the error names e.g. `bodies.0.material.youngs_modulus`.
pub(super) fn refine_key(root: &toml::Value, key: &str, message: &str) -> String {
    let join = |field: &str| {
        if key.is_empty() {
            field.to_string()
        } else {
            format!("{key}.{field}")
        }
    };
    let quoted = |prefix: &str| {
        message
            .strip_prefix(prefix)
            .and_then(|rest| rest.split('`').next())
            .map(str::to_string)
    };
    let Some(toml::Value::Table(table)) = value_at(root, key) else {
        return key.to_string();
    };
    let names_field = |field: &str| key == field || key.ends_with(&format!(".{field}"));
    if let Some(field) = quoted("missing field `") {
        if !table.contains_key(&field) {
            return join(&field);
        }
    }
    if let Some(field) = quoted("unknown field `") {
        if table.contains_key(&field) && !names_field(&field) {
            return join(&field);
        }
    }
    if let Some(variant) = quoted("unknown variant `") {
        let hits: Vec<&String> = table
            .iter()
            .filter(|(_, v)| v.as_str() == Some(variant.as_str()))
            .map(|(k, _)| k)
            .collect();
        if let [one] = hits[..] {
            return join(one);
        }
    }
    for prefix in ["invalid type: ", "invalid value: "] {
        if let Some(rest) = message.strip_prefix(prefix) {
            let found = rest.split(", expected ").next().unwrap_or("");
            let hits: Vec<&String> = table
                .iter()
                .filter(|(_, v)| unexpected(v) == found)
                .map(|(k, _)| k)
                .collect();
            if let [one] = hits[..] {
                return join(one);
            }
        }
    }
    key.to_string()
}

/// What an untagged value (one of several shapes) accepts, by key.
pub(super) fn untagged_expectation(key: &str) -> Option<&'static str> {
    let last = key.rsplit('.').next().unwrap_or("");
    match last {
        "beta" => Some("\"energy\", \"trapezoid\" or a number in [0, 1]"),
        "velocity" if key.contains(".constraints.") => {
            Some("an array of numbers [m/s] or a table of some components, e.g. { y = 0.0 }")
        }
        "initial_angular_velocity" | "angular_velocity" => {
            Some("a number [rad/s] in 2D, [wx, wy, wz] [rad/s] in 3D")
        }
        _ => None,
    }
}

/// Turns serde's "invalid type: string \"a\", expected f64" into (found, expected).
pub(super) fn split_serde_message(msg: &str) -> (String, String) {
    if let Some(i) = msg.find(", expected ") {
        let found = msg[..i]
            .trim_start_matches("invalid type: ")
            .trim_start_matches("invalid value: ");
        let expected = match &msg[i + ", expected ".len()..] {
            "f64" => "a number",
            "i64" => "an integer",
            "a boolean" | "bool" => "true or false",
            // serde's name of a Rust type (`struct SimulationSection`): a table to the user.
            other if other.starts_with("struct ") => "a table of keys",
            // The tagged tables (`friction`, `material`, `shape`): what the tag key is.
            "internally tagged enum FrictionSpec" => {
                "a table naming its law, e.g. { law = \"coulomb\", coefficient = 0.3 }"
            }
            "internally tagged enum MaterialSpec" => {
                "a table naming its model, e.g. { model = \"linear_elastic\", youngs_modulus = \
                 1e6, poissons_ratio = 0.3, density = 1000.0 }"
            }
            "internally tagged enum ShapeSpec" => {
                "a table naming its type, e.g. { type = \"halfspace\", point = [0.0, 0.0], \
                 normal = [0.0, 1.0] }"
            }
            other if other.starts_with("internally tagged enum ") => {
                "a table with its documented keys"
            }
            // The tag's value (`law = 3`): a name.
            "variant identifier" => "one of the documented names, as a string",
            other if other.starts_with("enum ") => "one of the documented values",
            other => other,
        };
        return (readable_number(found), expected.to_string());
    }
    if let Some(rest) = msg.strip_prefix("missing field ") {
        return ("nothing".into(), format!("the required key {rest}"));
    }
    (
        msg.to_string(),
        "a value of the documented type (see scene-format.md)".into(),
    )
}

/// serde prints a float in full (`floating point `1000...0.0``, 309 digits for 1e308): the
/// long ones in the messages' [`super::plain`] notation (short ones keep serde's `3.0`, which
/// says it is not an integer).
fn readable_number(found: &str) -> String {
    let Some(digits) = found
        .strip_prefix("floating point `")
        .and_then(|r| r.strip_suffix('`'))
    else {
        return found.to_string();
    };
    match digits.parse::<f64>() {
        Ok(x) if digits.len() > 12 => format!("floating point `{}`", super::plain(x)),
        _ => found.to_string(),
    }
}

/// The 1-based line where a dotted key (or its deepest existing parent) is defined.
pub(super) fn line_of(text: &str, key: &str) -> Option<usize> {
    use toml::de::{DeTable, DeValue};
    let doc = DeTable::parse(text).ok()?;
    let mut span = None;
    let mut table: Option<&DeTable> = Some(doc.get_ref());
    let mut array: Option<&[toml::Spanned<DeValue>]> = None;
    for part in key.split('.') {
        // A part that is not in the file (a missing key): stop at its deepest existing parent.
        let value = if let Some(items) = array.take() {
            match part.parse::<usize>().ok().and_then(|i| items.get(i)) {
                Some(v) => v,
                None => break,
            }
        } else {
            let Some(t) = table.take() else { break };
            let Some((k, v)) = t.iter().find(|(k, _)| k.get_ref().as_ref() == part) else {
                break;
            };
            span = Some(k.span());
            v
        };
        if span.is_none() || matches!(value.get_ref(), DeValue::Table(_)) {
            span = Some(value.span());
        }
        match value.get_ref() {
            DeValue::Table(t) => table = Some(t),
            DeValue::Array(a) => array = Some(a.as_ref()),
            _ => {}
        }
    }
    let start = span?.start;
    Some(text[..start.min(text.len())].matches('\n').count() + 1)
}
