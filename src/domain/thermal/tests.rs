use super::*;

#[test]
fn parameters_default_as_documented_and_out_of_range_ones_are_named() {
    let fit = ThermalParams::default().checked().unwrap();
    let (tolerance, o) = (fit.tolerance_k, fit.options);
    assert_eq!(tolerance, 0.5);
    assert_eq!(fit.params, ThermalParams::default());
    assert_eq!(
        (o.degree, o.reference_c, o.selection),
        (None, None, Selection::Backward)
    );
    assert_eq!((o.min_span_k, o.max_condition), (10.0, 100.0));
    let named = |p: ThermalParams| p.checked().unwrap_err().name;
    assert_eq!(
        named(ThermalParams {
            tolerance_k: Some(f64::NAN),
            ..Default::default()
        }),
        "tolerance_k"
    );
    assert_eq!(
        named(ThermalParams {
            reference_c: Some(300.0),
            ..Default::default()
        }),
        "reference_c"
    );
    assert_eq!(
        named(ThermalParams {
            degree: Some(4),
            ..Default::default()
        }),
        "degree"
    );
    assert_eq!(
        named(ThermalParams {
            min_span_k: Some(-1.0),
            ..Default::default()
        }),
        "min_span_k"
    );
    assert_eq!(
        named(ThermalParams {
            max_condition: Some(0.5),
            ..Default::default()
        }),
        "max_condition"
    );
}

#[test]
fn a_refusal_says_where_to_add_a_set_point() {
    let at = [20.0, 22.0, 40.0];
    let gap = refusal(
        &ThermalError::TooFewSetPoints {
            distinct: 3,
            degree: 3,
            needed: 5,
        },
        &at,
    );
    assert!(gap.to_string().contains("add 2 more"), "{gap}");
    assert!(gap.to_string().contains("e.g. at 31 °C"), "{gap}");
    assert_eq!(widest_gap(&[5.0]), None);
}
