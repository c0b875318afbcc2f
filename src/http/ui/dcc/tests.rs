//! Tests of [`super`].

use super::*;

#[test]
fn units_read_as_d_si() {
    assert_eq!(dsi_unit("mA"), r"\milli\ampere");
    assert_eq!(dsi_unit("µA"), r"\micro\ampere");
    assert_eq!(dsi_unit("uA"), r"\micro\ampere");
    assert_eq!(dsi_unit("V"), r"\volt");
    assert_eq!(dsi_unit("mV"), r"\milli\volt");
    assert_eq!(dsi_unit("kHz"), r"\kilo\hertz");
    assert_eq!(dsi_unit("m/s²"), r"\metre\second\tothe{-2}");
    assert_eq!(dsi_unit("LSB"), r"\one");
    assert_eq!(dsi_unit("output"), "|output");
    assert_eq!(dsi_unit("deg F"), "|degF");
    assert_eq!(dsi_unit("mmA"), "|mmA");
}

#[test]
fn numbers_match_d_si_patterns() {
    assert_eq!(probability(0.9545), "0.9545");
    assert_eq!(probability(0.883_883_476_483_184_4), "0.8839");
    assert_eq!(coverage_factor(2.0), "2");
    assert_eq!(coverage_factor(2.5), "2.5");
    assert_eq!(decimal(-1.25e-7), "-0.000000125");
}

#[test]
fn conditional_verdicts_split_by_the_value() {
    assert_eq!(conformity("pass", 0.0, None, None), "pass");
    assert_eq!(conformity("fail", 0.0, None, None), "fail");
    assert_eq!(
        conformity("conditional", 1.0, Some(0.0), Some(2.0)),
        "conditionalPass"
    );
    assert_eq!(
        conformity("conditional", 2.1, Some(0.0), Some(2.0)),
        "conditionalFail"
    );
    assert_eq!(
        conformity("conditional", -0.1, Some(0.0), None),
        "conditionalFail"
    );
}

#[test]
fn accept_negotiation() {
    let h = |v: &str| {
        let mut m = HeaderMap::new();
        m.insert(
            header::ACCEPT,
            axum::http::HeaderValue::from_str(v).unwrap(),
        );
        m
    };
    assert!(!prefers_xml(&HeaderMap::new()));
    assert!(prefers_xml(&h("application/xml")));
    assert!(prefers_xml(&h("text/xml")));
    assert!(!prefers_xml(&h("text/html,application/xml;q=0.9")));
    assert!(prefers_xml(&h("application/xml, */*;q=0.1")));
    assert!(!prefers_xml(&h("*/*")));
    assert!(!prefers_xml(&h("application/xml;q=0.5, text/html")));
}

#[test]
fn a_country_is_two_capital_letters() {
    use crate::http::Laboratory;
    assert_eq!(Laboratory::country_from("DE"), Ok("DE".to_owned()));
    for bad in ["de", "DEU", "D", "", "D1"] {
        assert!(Laboratory::country_from(bad).is_err(), "{bad}");
    }
}
