use super::*;

/// Points of `c(T) = Σ a_d (T − 20)^d` at `temperatures`, each `± u`.
fn planted(a: &[f64], temperatures: &[f64], u: f64) -> Vec<Point> {
    temperatures
        .iter()
        .map(|&t| Point {
            temperature_c: t,
            value: a
                .iter()
                .enumerate()
                .map(|(d, a)| a * (t - 20.0).powi(d as i32))
                .sum(),
            std_uncertainty: u,
        })
        .collect()
}

const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

#[test]
fn runs_within_the_tolerance_of_the_coolest_form_one_set_point() {
    let s = set_points(&[20.2, -19.9, 20.6, -20.1, 20.8, 40.0], 0.5);
    assert_eq!(
        s.iter().map(|p| p.runs.clone()).collect::<Vec<_>>(),
        [vec![1, 3], vec![0, 2], vec![4], vec![5]],
        "20.8 is 0.6 K above 20.2: a set point of its own"
    );
    assert!((s[0].temperature_c + 20.0).abs() < 1e-12);
    assert!((s[1].temperature_c - 20.4).abs() < 1e-12);
}

#[test]
fn the_reference_is_the_mean_rounded_to_a_tenth() {
    assert_eq!(reference(&CHAMBER), 20.0);
    assert_eq!(reference(&[-20.04, 0.0, 25.0]), 1.7);
}

#[test]
fn an_exact_cubic_is_recovered_with_no_inflation() {
    let a = [1e-3, 2e-5, -3e-7, 4e-9];
    let p = fit(
        &planted(&a, &CHAMBER, 1e-5),
        &Options {
            degree: Some(3),
            ..Options::default()
        },
    )
    .unwrap();
    assert_eq!((p.degree, p.dof, p.reference_c), (3, 1, 20.0));
    for (got, want) in p.coefficients.iter().zip(a) {
        assert!(
            (got - want).abs() < 1e-12 * want.abs().max(1e-3),
            "{got} vs {want}"
        );
    }
    assert_eq!(p.inflation, 1.0);
    assert_eq!(p.range_c, [-20.0, 60.0]);
    // At a set point, the value is the planted one; the slope is c'(T).
    let (v, u) = p.at(40.0);
    assert!((v - planted(&a, &[40.0], 1.0)[0].value).abs() < 1e-12);
    assert!(u > 0.0 && u.is_finite());
    let h = 1e-3;
    let numeric = (p.at(33.0 + h).0 - p.at(33.0 - h).0) / (2.0 * h);
    assert!((p.slope(33.0) - numeric).abs() < 1e-9);
    assert_eq!(p.outside_k(70.5), 10.5);
    assert_eq!(p.outside_k(-25.0), 5.0);
    assert_eq!(p.outside_k(33.0), 0.0);
}

#[test]
fn the_selection_stops_at_a_straight_line_through_a_straight_line() {
    // A line with small scatter about it, well within u: degree 1.
    let mut points = planted(&[0.5, 1e-4], &CHAMBER, 1e-5);
    for (p, e) in points.iter_mut().zip([3.0, -2.0, 1.0, -4.0, 2.0]) {
        p.value += e * 1e-6;
    }
    let p = fit(&points, &Options::default()).unwrap();
    assert_eq!(p.degree, 1, "{:?}", p.selection);
    let flagged: Vec<bool> = p.selection.iter().map(FTest::flagged).collect();
    assert_eq!(
        flagged,
        [false, false, true],
        "cubic, quadratic dropped; the line kept"
    );
    let up = fit(
        &points,
        &Options {
            selection: Selection::Forward,
            ..Options::default()
        },
    )
    .unwrap();
    assert_eq!(up.degree, 1);
    let flagged: Vec<bool> = up.selection.iter().map(FTest::flagged).collect();
    assert_eq!(flagged, [true, false], "the line added, the quadratic not");
}

#[test]
fn the_birge_ratio_inflates_a_scatter_the_uncertainties_do_not_explain() {
    let mut points = planted(&[0.5], &CHAMBER, 1e-5);
    for (p, e) in points.iter_mut().zip([3.0, -2.0, 1.0, -4.0, 2.0]) {
        p.value += e * 1e-4; // ten times u
    }
    let p = fit(
        &points,
        &Options {
            degree: Some(0),
            ..Options::default()
        },
    )
    .unwrap();
    let chi2: f64 = [3.0, -2.0, 1.0, -4.0, 2.0f64]
        .iter()
        .map(|e| (e * 1e-4 - 0.0 * 1e-4) / 1e-5)
        .map(|r| r * r)
        .sum();
    // The mean of the errors is 0: χ² is their sum of squares over u².
    assert!((p.chi2 - chi2).abs() < 1e-6 * chi2);
    assert!((p.inflation - chi2 / 4.0).abs() < 1e-9 * chi2);
    let plain = 1e-5 / 5f64.sqrt();
    assert!((p.std_uncertainties[0] - plain * (chi2 / 4.0).sqrt()).abs() < 1e-15);
}

#[test]
fn too_few_set_points_too_small_a_span_or_a_bad_design_are_refused() {
    let two = planted(&[1.0], &[0.0, 40.0], 1e-5);
    assert_eq!(
        fit(
            &two,
            &Options {
                degree: Some(1),
                ..Options::default()
            }
        ),
        Err(ThermalError::TooFewSetPoints {
            distinct: 2,
            degree: 1,
            needed: 3
        })
    );
    let narrow = planted(&[1.0], &[20.0, 22.0, 24.0], 1e-5);
    assert!(matches!(
        fit(&narrow, &Options::default()),
        Err(ThermalError::SpanTooSmall { span_k, .. }) if (span_k - 4.0).abs() < 1e-12
    ));
    let crowded = planted(&[1.0], &[20.0, 20.6, 21.2, 35.0], 1e-5);
    assert!(matches!(
        fit(
            &crowded,
            &Options {
                degree: Some(2),
                max_condition: 10.0,
                ..Options::default()
            }
        ),
        Err(ThermalError::IllConditioned { degree: 2, .. })
    ));
    assert_eq!(
        fit(
            &two,
            &Options {
                degree: Some(4),
                ..Options::default()
            }
        ),
        Err(ThermalError::DegreeTooHigh(4))
    );
    let mut unweighted = planted(&[1.0], &CHAMBER, 1e-5);
    unweighted[2].std_uncertainty = 0.0;
    assert_eq!(
        fit(&unweighted, &Options::default()),
        Err(ThermalError::Unweighted {
            temperature_c: 20.0
        })
    );
}

#[test]
fn weights_at_the_edge_of_f64_are_refused_not_served_as_infinities() {
    let mut points = planted(&[1.0], &CHAMBER, 1e-5);
    points[0].std_uncertainty = 1e-300;
    // Tiny but finite: the covariance underflows to zero, still finite.
    assert!(fit(&points, &Options::default()).is_ok());
    // At degree 3, (T − T_ref)³ / u overflows: refused, not factorised.
    let cubic = Options {
        degree: Some(3),
        ..Options::default()
    };
    assert_eq!(fit(&points, &cubic), Err(ThermalError::NotFinite));
    points[0].value = 1e300; // value / u overflows too
    assert_eq!(
        fit(&points, &Options::default()),
        Err(ThermalError::NotFinite)
    );
    // Only value / u overflows: the solution is not finite.
    let mut points = planted(&[1.0], &CHAMBER, 1e-5);
    points[0].value = 1e300;
    points[0].std_uncertainty = 1e-10;
    assert_eq!(fit(&points, &cubic), Err(ThermalError::NotFinite));
}

#[test]
fn a_span_of_exactly_the_minimum_is_enough_and_a_singular_design_is_infinitely_ill_conditioned() {
    let points = planted(&[1.0], &[20.0, 25.0, 30.0], 1e-5);
    assert_eq!(
        fit(&points, &Options::default()).unwrap().range_c,
        [20.0, 30.0]
    );
    assert_eq!(condition(&[20.0, 20.0, 20.0], 20.0, 1), f64::INFINITY);
    assert!(
        (condition(&CHAMBER, 20.0, 1) - 1.0).abs() < 1e-12,
        "orthogonal columns"
    );
}

#[test]
fn a_top_degree_past_the_condition_limit_is_not_where_the_elimination_starts() {
    // Four set points within 2 K and a fifth 13 K away: the cubic's design
    // is past 100, the quadratic's not; a planted quadratic, exactly.
    let t = [20.0, 20.6, 21.2, 21.8, 35.0];
    let mut points = planted(&[0.5, 1e-3, 2e-4], &t, 1e-6);
    for (p, e) in points.iter_mut().zip([1.0, -1.0, 0.5, -0.5, 0.2]) {
        p.value += e * 1e-7;
    }
    let reference_c = reference(&t);
    assert!(condition(&t, reference_c, 3) > 100.0 && condition(&t, reference_c, 2) < 100.0);
    let p = fit(&points, &Options::default()).unwrap();
    assert_eq!(p.degree, 2);
    assert_eq!(p.selection.len(), 1, "from degree 2: one test, significant");
    assert_eq!(p.selection[0].df2, 2, "N − D − 1 at D = 2");
    // A limit exactly at the design's condition number admits it.
    let at_limit = Options {
        degree: Some(2),
        max_condition: condition(&t, reference_c, 2),
        ..Options::default()
    };
    assert_eq!(fit(&points, &at_limit).unwrap().degree, 2);
    // Forward selection on four set points tries degree 2 at most (N − 2).
    let four = planted(&[0.5, 1e-3, 2e-4, 3e-6], &CHAMBER[..4], 1e-6);
    let up = fit(
        &four,
        &Options {
            selection: Selection::Forward,
            ..Options::default()
        },
    )
    .unwrap();
    assert!(
        up.degree <= 2 && up.selection.iter().all(|t| t.df2 >= 1),
        "{up:?}"
    );
}

#[test]
fn an_overflowed_weight_gives_a_fit_of_the_asked_shape_all_nan() {
    // A standard uncertainty so small that 1/u overflows: the design holds
    // infinities, and the fit is NaN throughout, with the shape of the
    // degree asked for (what `fit` then refuses as not finite).
    let points: Vec<Point> = [10.0, 20.0, 30.0, 40.0]
        .iter()
        .map(|&t| Point {
            temperature_c: t,
            value: 1.0,
            std_uncertainty: 1e-320,
        })
        .collect();
    for degree in [0, 2] {
        let (a, cov, chi2) = weighted(&points, 25.0, degree);
        assert_eq!(a.len(), degree + 1);
        assert_eq!(cov.shape(), (degree + 1, degree + 1));
        assert!(a.iter().chain(cov.iter()).all(|x| x.is_nan()));
        assert!(chi2.is_nan());
    }
}
