//! Finding the session a user means: by id, by name, or by a unique prefix of a name; and
//! when that fails, the names they may have meant.

use super::StoreError;
use super::session::Session;

pub enum Miss {
    None(Vec<String>),
    Several(Vec<String>),
}

/// Names are free text, but never all digits: a key of digits is always an id.
pub fn check_name(name: &str) -> Result<(), StoreError> {
    let bad = |reason| {
        Err(StoreError::BadName {
            name: name.to_string(),
            reason,
        })
    };
    if name.trim().is_empty() {
        bad("empty")
    } else if name.chars().all(|c| c.is_ascii_digit()) {
        bad("all digits (it would read as a session id)")
    } else if name.chars().any(char::is_control) {
        bad("control characters")
    } else if name.len() > 200 {
        bad("longer than 200 bytes")
    } else {
        Ok(())
    }
}

pub fn find(sessions: &[Session], key: &str) -> Result<Session, Miss> {
    if let Ok(id) = key.parse::<i64>() {
        return sessions
            .iter()
            .find(|s| s.id == id)
            .cloned()
            .ok_or_else(|| Miss::None(close(sessions, key)));
    }
    if let Some(s) = sessions.iter().find(|s| s.name == key) {
        return Ok(s.clone());
    }
    let prefixed: Vec<&Session> = sessions
        .iter()
        .filter(|s| s.name.starts_with(key))
        .collect();
    match prefixed.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(Miss::None(close(sessions, key))),
        several => Err(Miss::Several(several.iter().map(|s| label(s)).collect())),
    }
}

fn label(s: &Session) -> String {
    format!("{} ({})", s.name, s.id)
}

/// Up to five sessions whose name contains the key or is within a few edits of it.
fn close(sessions: &[Session], key: &str) -> Vec<String> {
    let key_lower = key.to_lowercase();
    let mut scored: Vec<(usize, &Session)> = sessions
        .iter()
        .filter_map(|s| {
            let name = s.name.to_lowercase();
            let d = if name.contains(&key_lower) || key_lower.contains(&name) {
                0
            } else {
                edit_distance(&name, &key_lower)
            };
            (d <= 3.max(key.len() / 3)).then_some((d, s))
        })
        .collect();
    scored.sort_by_key(|(d, s)| (*d, s.id));
    scored.into_iter().take(5).map(|(_, s)| label(s)).collect()
}

pub fn suggest(close: &[String]) -> String {
    if close.is_empty() {
        "; `imunoise sessions` lists them".to_string()
    } else {
        format!("; did you mean: {}?", close.join(", "))
    }
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (diagonal + usize::from(ca != *cb))
                .min(row[j] + 1)
                .min(row[j + 1] + 1);
            diagonal = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_names() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "ab"), 2);
        assert!(check_name("123").is_err());
        assert!(check_name("bench-1").is_ok());
        assert!(check_name(" ").is_err());
    }
}
