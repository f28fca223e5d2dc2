//! Every tool's settings struct through JSON: its defaults come back as they went, a partial
//! object changes only what it names, `null` turns an optional stage off, and a key the
//! struct does not have is refused by its path.

use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{json, Value};
use shapesmith_native::analysis::AnalysisParams;
use shapesmith_native::landmarks::{Criterion, LandmarkParams, ScoreParams};
use shapesmith_native::packing::PackingParams;
use shapesmith_native::performance::PerformanceParams;
use shapesmith_native::settings::{settings_from_json, settings_to_json};
use shapesmith_native::transfer::TransferShapesParams;
use shapesmith_native::wrap::{CarryParams, WrapParams};
use shapesmith_native::ShapesmithError;

fn round_trip<T: Serialize + DeserializeOwned + Default>(tool: &str) {
    let defaults = settings_to_json(&T::default());
    assert!(defaults.is_object(), "{tool}: {defaults}");
    let back: T = settings_from_json(defaults.clone(), tool).unwrap();
    assert_eq!(settings_to_json(&back), defaults, "{tool}");
    let empty: T = settings_from_json(json!({}), tool).unwrap();
    assert_eq!(settings_to_json(&empty), defaults, "{tool}: an empty object is the defaults");
    match settings_from_json::<T>(json!({"no_such_option": 1}), tool) {
        Err(ShapesmithError::InvalidInput(message)) => {
            assert!(message.starts_with(&format!("{tool} settings: `no_such_option`: unknown field")), "{message}")
        }
        other => panic!("{tool}: an unknown key was accepted: {:?}", other.map(|t| settings_to_json(&t))),
    }
}

#[test]
fn every_tools_defaults_round_trip_and_unknown_keys_are_refused() {
    round_trip::<AnalysisParams>("analyze");
    round_trip::<PackingParams>("pack");
    round_trip::<LandmarkParams>("landmarks");
    round_trip::<ScoreParams>("score");
    round_trip::<TransferShapesParams>("transfer");
    round_trip::<PerformanceParams>("performance");
    round_trip::<WrapParams>("wrap");
    round_trip::<CarryParams>("carry");
}

#[test]
fn a_partial_transfer_object_changes_only_what_it_names() {
    let given = json!({"transfer": {"virtual_edges": {"tau_d": 0.02}, "contact": {"distance": 0.1}}, "compare_plain": true});
    let params: TransferShapesParams = settings_from_json(given, "transfer").unwrap();
    let defaults = TransferShapesParams::default();
    let edges = params.transfer.virtual_edges.unwrap();
    assert_eq!(edges.tau_d, 0.02);
    assert_eq!(edges.tau_r, defaults.transfer.virtual_edges.unwrap().tau_r);
    assert_eq!(params.transfer.contact.map(|c| c.distance), Some(0.1));
    assert!(defaults.transfer.contact.is_none() && params.compare_plain && params.measure_penetration);
    assert_eq!(params.personalise, defaults.personalise);
    assert_eq!(params.transfer.edge_weight, defaults.transfer.edge_weight);
}

#[test]
fn the_rigs_data_is_no_setting() {
    // Shape indices and stored results travel beside the settings, never inside them.
    for (key, value) in [("exclude", json!([0])), ("pairs", json!([[0, 1]])), ("known", Value::Null)] {
        let refused = settings_from_json::<PackingParams>(json!({ key: value }), "pack");
        assert!(matches!(refused, Err(ShapesmithError::InvalidInput(ref m)) if m.contains("unknown field")), "{key}");
    }
    assert!(!settings_to_json(&LandmarkParams::default()).as_object().unwrap().contains_key("cameras"));
    let landmarks: LandmarkParams = settings_from_json(json!({"criterion": "d", "landmarks": 30}), "landmarks").unwrap();
    assert_eq!((landmarks.criterion, landmarks.landmarks), (Criterion::D, Some(30)));
    let refused = settings_from_json::<LandmarkParams>(json!({"criterion": "x"}), "landmarks");
    assert!(matches!(refused, Err(ShapesmithError::InvalidInput(ref m)) if m.contains("`criterion`")));
}
