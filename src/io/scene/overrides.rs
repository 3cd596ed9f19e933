//! `--set KEY=VALUE` overrides, applied to the TOML table before deserialisation.

/// Applies one `--set KEY=VALUE` to the parsed table (dotted keys; `bodies.0.` and
/// `obstacles.NAME.` address list items); returns the key path with indices, e.g.
/// `obstacles.2.velocity`, for error locations.
pub(super) fn apply_override(
    table: &mut toml::Table,
    assignment: &str,
) -> std::result::Result<String, String> {
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE, e.g. simulation.time_step=2e-4".to_string())?;
    let key = key.trim();
    let literal: toml::Table = toml::from_str(&format!("v = {}", value.trim()))
        .map_err(|e| format!("the value is not a TOML literal ({})", e.message()))?;
    let value = literal.get("v").cloned().ok_or("empty value")?;
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!("`{key}` is not a dotted key path"));
    }
    let mut current = table;
    let mut path = Vec::new();
    let mut i = 0;
    while i + 1 < parts.len() {
        let part = parts[i];
        path.push(part.to_string());
        let entry = current
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        current = match entry {
            toml::Value::Table(t) => t,
            toml::Value::Array(items) => {
                i += 1;
                let selector = parts[i];
                let index = match selector.parse::<usize>() {
                    Ok(n) => n,
                    Err(_) => items
                        .iter()
                        .position(|it| it.get("name").and_then(|n| n.as_str()) == Some(selector))
                        .ok_or_else(|| format!("no item of `{part}` is named `{selector}`"))?,
                };
                path.push(index.to_string());
                let len = items.len();
                match items.get_mut(index) {
                    Some(toml::Value::Table(t)) => t,
                    _ => {
                        return Err(format!(
                            "`{part}` has {len} items; index {index} is out of range"
                        ))
                    }
                }
            }
            _ => return Err(format!("`{}` is not a table", path.join("."))),
        };
        i += 1;
    }
    if i >= parts.len() {
        return Err(format!("`{key}` names a list item, not a key"));
    }
    path.push(parts[i].to_string());
    current.insert(parts[i].to_string(), value);
    Ok(path.join("."))
}
