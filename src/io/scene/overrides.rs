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
    let literal: toml::Table = toml::from_str(&format!("v = {}", value.trim())).map_err(|e| {
        // Say what the key holds now rather than the parser's guess ("invalid boolean").
        let expected = match existing(table, key.trim()) {
            Some(toml::Value::Float(_) | toml::Value::Integer(_)) => {
                "a number was expected (e.g. 2e-4)".to_string()
            }
            Some(toml::Value::String(s)) => format!("a quoted string was expected (e.g. \"{s}\")"),
            Some(toml::Value::Boolean(_)) => "true or false was expected".to_string(),
            _ => format!(
                "expected a number, a quoted string, true, false or an array ({})",
                e.message().trim_end()
            ),
        };
        format!("`{}` is not a TOML literal: {expected}", value.trim())
    })?;
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

/// The value a dotted key holds in the table, if any (`bodies.0.` and `obstacles.NAME.` address
/// list items).
fn existing<'a>(table: &'a toml::Table, key: &str) -> Option<&'a toml::Value> {
    let mut parts = key.split('.');
    let mut value = table.get(parts.next()?)?;
    for part in parts {
        value = match value {
            toml::Value::Table(t) => t.get(part)?,
            toml::Value::Array(items) => match part.parse::<usize>() {
                Ok(n) => items.get(n)?,
                Err(_) => items
                    .iter()
                    .find(|it| it.get("name").and_then(|n| n.as_str()) == Some(part))?,
            },
            _ => return None,
        };
    }
    Some(value)
}
