//! Each tool's settings as one JSON object onto its `*Params` struct, the one place its
//! defaults are written.
//!
//! Every `*Params` struct a caller may set derives serde's `Deserialize` with
//! `#[serde(default, deny_unknown_fields)]`: a key left out keeps its default, a nested
//! struct may be given in part, `null` turns an optional stage off (`"contact": null`), and
//! a key the struct does not have (a misspelt option) is refused. What is not a setting (the
//! rig's data: arrays, shape-name lists, a stored cache) is `#[serde(skip)]` and reaches the
//! core through the entry point's own arguments.

use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{Map, Value};

use crate::error::ShapesmithResult;
use crate::invalid;

/// `T` from a JSON object of `tool`'s settings (`null`: the defaults). An unknown key, a
/// value of the wrong type or a JSON that is no object is an `InvalidInput` naming the key's
/// path (`transfer.virtual_edges.tau_d`).
pub fn settings_from_json<T: DeserializeOwned + Default>(value: Value, tool: &str) -> ShapesmithResult<T> {
    match value {
        Value::Null => Ok(T::default()),
        Value::Object(_) => serde_json::from_value::<T>(value.clone()).map_err(|error| {
            let path = failing_path::<T>(&value, &[]).map_or_else(String::new, |path| format!(" `{}`:", path.join(".")));
            invalid!("{tool} settings:{path} {}", without_position(&error.to_string()))
        }),
        other => Err(invalid!("{tool} settings must be a dict of option names to values, got {other}")),
    }
}

/// The settings as a JSON object (the defaults a binding hands out, the report's echo).
pub fn settings_to_json<T: Serialize>(settings: &T) -> Value {
    // Every field of a settings struct is a number, a bool, a string, a list or a struct of
    // those, which serde_json always represents.
    serde_json::to_value(settings).unwrap_or(Value::Null)
}

/// The path of keys to the first value `T` refuses: each key of `value` is tried alone
/// (nested inside the keys above it), descending into objects, so the message can name the
/// option rather than a position in a JSON text.
fn failing_path<T: DeserializeOwned>(value: &Value, above: &[String]) -> Option<Vec<String>> {
    let Value::Object(map) = value else { return None };
    for (key, inner) in map {
        let path: Vec<String> = above.iter().cloned().chain([key.clone()]).collect();
        if serde_json::from_value::<T>(nested(&path, inner.clone())).is_err() {
            return failing_path::<T>(inner, &path).or(Some(path));
        }
    }
    None
}

/// `{"a": {"b": value}}` for the path `[a, b]`.
fn nested(path: &[String], value: Value) -> Value {
    path.iter().rev().fold(value, |inner, key| Value::Object(Map::from_iter([(key.clone(), inner)])))
}

/// serde_json's message without its " at line 1 column 12", which points into a text the
/// caller never wrote.
fn without_position(message: &str) -> &str {
    message.find(" at line ").map_or(message, |at| &message[..at])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ShapesmithError;
    use serde::Deserialize;

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Inner {
        width: f64,
        count: usize,
    }

    impl Default for Inner {
        fn default() -> Self {
            Self { width: 0.5, count: 3 }
        }
    }

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Outer {
        inner: Option<Inner>,
        on: bool,
    }

    impl Default for Outer {
        fn default() -> Self {
            Self { inner: Some(Inner::default()), on: true }
        }
    }

    fn message(result: ShapesmithResult<Outer>) -> String {
        match result {
            Err(ShapesmithError::InvalidInput(message)) => message,
            other => panic!("expected InvalidInput, got {other:?}"),
        }
    }

    #[test]
    fn missing_keys_keep_their_defaults_and_null_turns_a_stage_off() {
        assert_eq!(settings_from_json::<Outer>(Value::Null, "t").unwrap(), Outer::default());
        let partial: Outer = settings_from_json(serde_json::json!({"inner": {"count": 7}}), "t").unwrap();
        assert_eq!(partial, Outer { inner: Some(Inner { width: 0.5, count: 7 }), on: true });
        let off: Outer = settings_from_json(serde_json::json!({"inner": null}), "t").unwrap();
        assert_eq!(off.inner, None);
    }

    #[test]
    fn defaults_round_trip_through_json() {
        let changed = Outer { inner: Some(Inner { width: 0.125, count: 9 }), on: false };
        for settings in [Outer::default(), changed] {
            assert_eq!(settings_from_json::<Outer>(settings_to_json(&settings), "t").unwrap(), settings);
        }
    }

    #[test]
    fn an_unknown_key_is_named_with_its_path() {
        let text = message(settings_from_json(serde_json::json!({"on": false, "inner": {"widht": 1.0}}), "demo"));
        assert!(text.starts_with("demo settings: `inner.widht`: unknown field `widht`"), "{text}");
        assert!(text.contains("`width`") && !text.contains("line"), "{text}");
    }

    #[test]
    fn a_value_of_the_wrong_type_is_named_with_its_path() {
        let text = message(settings_from_json(serde_json::json!({"inner": {"count": -2}}), "demo"));
        assert!(text.starts_with("demo settings: `inner.count`: invalid value"), "{text}");
        let text = message(settings_from_json(serde_json::json!({"on": "yes"}), "demo"));
        assert!(text.starts_with("demo settings: `on`: invalid type"), "{text}");
        assert!(message(settings_from_json(serde_json::json!([1, 2]), "demo")).contains("must be a dict"));
    }
}
