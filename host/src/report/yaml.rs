//! Any JSON document as block YAML (YAML 1.2), for results people read and edit: mappings
//! and lists of mappings as blocks, lists of plain values inline (`[1.0, 2.0, 3.0]`, so a
//! matrix reads as rows). Strings are double-quoted with JSON's escapes, which are YAML's
//! too; keys are bare when they are plain words. Numbers print as serde_json prints them
//! (shortest round trip), with a dot in every exponent's mantissa (`number`).

use serde_json::Value;

/// `value` as a YAML document, after `#` comment lines `header`.
pub fn document(header: &[String], value: &Value) -> String {
    let mut out: String = header.iter().map(|h| format!("# {h}\n")).collect();
    match value {
        Value::Object(_) | Value::Array(_) if !is_flat(value) => block(value, 0, &mut out),
        _ => {
            out += &inline(value);
            out.push('\n');
        }
    }
    out
}

/// A list of plain values (or empty container) goes on one line.
fn is_flat(value: &Value) -> bool {
    match value {
        Value::Array(items) => items.iter().all(|v| !v.is_object() && is_flat(v)),
        Value::Object(map) => map.is_empty(),
        _ => true,
    }
}

fn inline(value: &Value) -> String {
    match value {
        Value::Array(items) => {
            let parts: Vec<String> = items.iter().map(inline).collect();
            format!("[{}]", parts.join(", "))
        }
        Value::Object(_) => "{}".into(),
        Value::Number(n) => number(&n.to_string()),
        other => other.to_string(),
    }
}

/// serde_json's `1e-7` is a float in YAML 1.2 but a string to YAML 1.1 readers (PyYAML),
/// which want a dot in the mantissa: `1.0e-7` reads as a float in both.
fn number(text: &str) -> String {
    match text.split_once(['e', 'E']) {
        Some((mantissa, exp)) if !mantissa.contains('.') => format!("{mantissa}.0e{exp}"),
        _ => text.to_string(),
    }
}

fn key(k: &str) -> String {
    let plain = !k.is_empty()
        && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !k.starts_with(|c: char| c.is_ascii_digit());
    if plain {
        k.to_string()
    } else {
        Value::String(k.to_string()).to_string()
    }
}

/// A non-flat mapping or list at `indent` spaces.
fn block(value: &Value, indent: usize, out: &mut String) {
    let pad = " ".repeat(indent);
    match value {
        Value::Object(map) => {
            for (k, v) in map {
                if is_flat(v) {
                    out.push_str(&format!("{pad}{}: {}\n", key(k), inline(v)));
                } else {
                    out.push_str(&format!("{pad}{}:\n", key(k)));
                    block(v, indent + 2, out);
                }
            }
        }
        Value::Array(items) => {
            for v in items {
                if is_flat(v) {
                    out.push_str(&format!("{pad}- {}\n", inline(v)));
                } else {
                    // The item's block, its first line after "- ".
                    let mut item = String::new();
                    block(v, indent + 2, &mut item);
                    out.push_str(&format!("{pad}- {}", &item[indent + 2..]));
                }
            }
        }
        other => out.push_str(&format!("{pad}{}\n", inline(other))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_document_as_block_yaml() {
        let v = serde_json::json!({
            "id": 3,
            "board id": "0x53",
            "matrix": [[1.0, 0.5], [0.0, 1.0]],
            "none": null,
            "list": [{"sensor": "gyro", "bias": [0.1, -2e-5, 1e-7]}, {"sensor": "accel", "empty": []}],
            "nested": {"a": {"b": true}},
        });
        let want = "\
# made by a test
\"board id\": \"0x53\"
id: 3
list:
  - bias: [0.1, -0.00002, 1.0e-7]
    sensor: \"gyro\"
  - empty: []
    sensor: \"accel\"
matrix: [[1.0, 0.5], [0.0, 1.0]]
nested:
  a:
    b: true
none: null
";
        assert_eq!(document(&["made by a test".into()], &v), want);
        assert_eq!(document(&[], &serde_json::json!("a\"b")), "\"a\\\"b\"\n");
    }
}
