//! The settings serialise (as written beside every result) and read back;
//! missing fields take their defaults, unknown fields are refused.

use nonholo_integrate::{Options, Radau5Options, RadauDense, RadauNewton};

#[test]
fn options_round_trip_through_json() {
    let opts = Options {
        rtol: 1e-9,
        atol_components: Some(vec![1e-9, 1e-3]),
        fixed_step: Some(0.25),
        max_wall_time_s: Some(60.0),
        output: vec![0.5, 1.0],
        hit_output: true,
        radau5: Radau5Options {
            newton: RadauNewton::Full,
            newton_tol: Some(1e-6),
            keep_step: (0.9, 1.3),
            ..Radau5Options::default()
        },
        ..Options::default()
    };
    let json = serde_json::to_value(&opts).unwrap();
    assert_eq!(json["radau5"]["newton"], "full");
    assert_eq!(json["radau5"]["keep_step"], serde_json::json!([0.9, 1.3]));
    assert_eq!(json["h_init"], serde_json::Value::Null);
    let back: Options = serde_json::from_value(json).unwrap();
    assert_eq!(back, opts);
}

/// `dense_output` is always written: records made before it existed leave
/// it out and were made with the collocation polynomial, records made
/// since say which extension they used, the default `auto` included.
#[test]
fn dense_output_is_always_written() {
    let json = serde_json::to_value(Options::default()).unwrap();
    assert_eq!(json["radau5"]["dense_output"], "auto", "{json}");
    let opts = Options {
        radau5: Radau5Options {
            dense_output: RadauDense::Collocation,
            ..Radau5Options::default()
        },
        ..Options::default()
    };
    let json = serde_json::to_value(&opts).unwrap();
    assert_eq!(json["radau5"]["dense_output"], "collocation");
    assert_eq!(serde_json::from_value::<Options>(json).unwrap(), opts);
    assert!(serde_json::from_str::<Options>(r#"{"radau5": {"dense_output": "cubic"}}"#).is_err());
    for v in [
        RadauDense::Auto,
        RadauDense::Collocation,
        RadauDense::Hermite,
    ] {
        assert_eq!(serde_json::to_value(v).unwrap(), v.name());
        assert_eq!(RadauDense::from_name(v.name()), Some(v));
    }
    // `auto` is the Hermite extension for y' = f(t, y) only.
    assert!(RadauDense::Auto.hermite(true) && !RadauDense::Auto.hermite(false));
    assert!(RadauDense::Hermite.hermite(false) && !RadauDense::Collocation.hermite(true));
}

#[test]
fn missing_fields_default_and_unknown_fields_are_refused() {
    let opts: Options =
        serde_json::from_str(r#"{"rtol": 1e-8, "radau5": {"newton": "simplified"}}"#).unwrap();
    assert_eq!(
        opts,
        Options {
            rtol: 1e-8,
            radau5: Radau5Options {
                newton: RadauNewton::Simplified,
                ..Radau5Options::default()
            },
            ..Options::default()
        }
    );
    for bad in [
        r#"{"newton_tol": 1e-6}"#,
        r#"{"radau5": {"newton": "quasi"}}"#,
        r#"{"radau5": {"radau_newton": "full"}}"#,
    ] {
        assert!(serde_json::from_str::<Options>(bad).is_err(), "{bad}");
    }
    for v in [
        RadauNewton::Auto,
        RadauNewton::Simplified,
        RadauNewton::Full,
    ] {
        assert_eq!(serde_json::to_value(v).unwrap(), v.name());
    }
}
