//! Tests of [`super`].

use super::*;

fn principal(id: &str, role: Role, holder: Option<&str>) -> Principal {
    Principal {
        id: id.into(),
        role,
        station_id: None,
        holder: holder.map(Into::into),
    }
}

fn act(action: Action, signer: Principal) -> Act {
    Act {
        action,
        signer,
        at: Timestamp::parse("2026-11-25T10:00:00Z").unwrap(),
        comment: Some("checked".into()),
        superseded_by: None,
    }
}

fn by(token: &str, holder: Option<&str>) -> Submitter {
    Submitter {
        token_id: token.into(),
        holder: holder.map(Into::into),
        received_at: Timestamp::parse("2026-11-24T10:00:00Z").unwrap(),
        earlier: Vec::new(),
    }
}

/// Every (action, state) pair against the diagram in the module's doc.
#[test]
fn the_transitions_are_the_diagrams() {
    let reviewer = principal("r", Role::Reviewer, Some("R. Eviewer"));
    let submitter = by("s", Some("S. Tation"));
    let states = State::ALL;
    // Columns: submitted, approved, rejected, withdrawn, superseded,
    // under review.
    let expected = [
        (
            Action::Approve,
            [
                Some(State::Approved),
                None,
                None,
                None,
                None,
                Some(State::Approved),
            ],
        ),
        (
            Action::Reject,
            [Some(State::Rejected), None, None, None, None, None],
        ),
        (
            Action::Withdraw,
            [
                Some(State::Withdrawn),
                Some(State::Withdrawn),
                None,
                None,
                None,
                Some(State::Withdrawn),
            ],
        ),
        (
            Action::Supersede,
            [
                Some(State::Superseded),
                Some(State::Superseded),
                None,
                None,
                None,
                Some(State::Superseded),
            ],
        ),
        (
            Action::Hold,
            [
                Some(State::UnderReview),
                Some(State::UnderReview),
                None,
                None,
                None,
                None,
            ],
        ),
    ];
    let admin = principal("a", Role::Admin, Some("R. Eviewer"));
    for (action, targets) in expected {
        // A hold is an admin's act; a reviewer's is refused for the role.
        let signer = if action == Action::Hold {
            let refused = act(action, reviewer.clone()).check(State::Submitted, &submitter, 3);
            assert!(matches!(refused, Err(Refusal::Role { .. })), "{refused:?}");
            admin.clone()
        } else {
            reviewer.clone()
        };
        for (state, target) in states.iter().zip(targets) {
            let out = act(action, signer.clone()).check(*state, &submitter, 3);
            match target {
                Some(t) => {
                    let s = out.unwrap();
                    assert_eq!((s.state, s.seq, s.action), (t, 3, action));
                    assert_eq!(s.holder.as_deref(), Some("R. Eviewer"));
                }
                None => assert!(
                    matches!(out, Err(Refusal::State { state: s, .. }) if s == *state),
                    "{action:?} from {state:?}"
                ),
            }
        }
    }
}

/// The submitting token corrects its own calibration within 24 h of
/// its submission (received 2026-11-24T10:00Z); after that, and for any
/// other station, it takes a reviewer.
#[test]
fn a_station_supersedes_its_own_calibration_within_a_day() {
    let station = principal("s", Role::Station, Some("Sam"));
    let supersede = |signer: Principal, at: &str| {
        supersession(
            "wrong sensor id".into(),
            signer,
            Timestamp::parse(at).unwrap(),
            uuid::Uuid::from_u128(9),
        )
    };
    let own = by("s", Some("Sam"));
    let s = supersede(station.clone(), "2026-11-25T10:00:00Z")
        .check(State::Submitted, &own, 1)
        .unwrap();
    assert_eq!(
        (s.state, s.superseded_by),
        (State::Superseded, Some(uuid::Uuid::from_u128(9)))
    );
    let late = supersede(station.clone(), "2026-11-25T10:00:01Z").check(State::Submitted, &own, 1);
    assert!(matches!(late, Err(Refusal::Role { .. })), "{late:?}");
    let other = supersede(
        principal("t", Role::Station, Some("Sam")),
        "2026-11-24T11:00:00Z",
    )
    .check(State::Submitted, &own, 1);
    assert!(matches!(other, Err(Refusal::Role { .. })), "{other:?}");
    // A reviewer may, at any time, even their own; never twice.
    let reviewer = principal("s", Role::Reviewer, Some("Sam"));
    assert!(
        supersede(reviewer.clone(), "2027-01-01T00:00:00Z")
            .check(State::Approved, &own, 2)
            .is_ok()
    );
    for state in [State::Superseded, State::Withdrawn, State::Rejected] {
        let out = supersede(reviewer.clone(), "2027-01-01T00:00:00Z").check(state, &own, 2);
        assert!(matches!(out, Err(Refusal::State { .. })), "{state:?}");
    }
    assert_eq!(check_reason(Some("  moved  ")), Ok("moved".into()));
    assert!(check_reason(None).is_err());
    assert!(check_reason(Some(" ")).is_err());
}

#[test]
fn readers_and_stations_may_not_sign() {
    for role in [Role::Reader, Role::Station] {
        for action in [Action::Approve, Action::Reject, Action::Withdraw] {
            let out =
                act(action, principal("x", role, None)).check(State::Submitted, &by("s", None), 1);
            let e = out.unwrap_err();
            assert!(e.is_permission());
            assert!(e.to_string().contains("reviewer or admin"), "{e}");
        }
    }
    let admin = act(Action::Approve, principal("a", Role::Admin, None));
    assert!(admin.check(State::Submitted, &by("s", None), 1).is_ok());
}

#[test]
fn nobody_reviews_their_own_work() {
    let cases = [
        // Same holder on two tokens.
        (
            principal("r", Role::Reviewer, Some("Ann")),
            by("s", Some("Ann")),
            true,
        ),
        // The same token, with or without a holder.
        (principal("t", Role::Admin, None), by("t", None), true),
        (
            principal("t", Role::Admin, Some("Ann")),
            by("t", Some("Ann")),
            true,
        ),
        // Different holders; different tokens without holders.
        (
            principal("r", Role::Reviewer, Some("Bob")),
            by("s", Some("Ann")),
            false,
        ),
        (principal("r", Role::Reviewer, None), by("s", None), false),
        (
            principal("r", Role::Reviewer, Some("Ann")),
            by("s", None),
            false,
        ),
    ];
    for (signer, submitter, own) in cases {
        for action in [Action::Approve, Action::Reject] {
            let out = act(action, signer.clone()).check(State::Submitted, &submitter, 1);
            assert_eq!(
                matches!(out, Err(Refusal::OwnWork { .. })),
                own,
                "{signer:?} {submitter:?}"
            );
        }
        // Withdrawing one's own calibration is allowed.
        assert!(
            act(Action::Withdraw, signer)
                .check(State::Approved, &submitter, 1)
                .is_ok()
        );
    }
}

/// Approving a held calibration releases the hold: only with a
/// disposition in the comment.
#[test]
fn a_hold_is_released_by_a_disposition() {
    let reviewer = principal("r", Role::Reviewer, Some("R"));
    let mut a = act(Action::Approve, reviewer);
    a.comment = None;
    let refused = a.check(State::UnderReview, &by("s", None), 2);
    assert_eq!(refused, Err(Refusal::Disposition));
    assert!(!Refusal::Disposition.is_permission());
    assert!(a.check(State::Submitted, &by("s", None), 2).is_ok());
    a.comment = Some("no effect: the 9″ error is within kp's tolerance".into());
    let s = a.check(State::UnderReview, &by("s", None), 2).unwrap();
    assert_eq!(s.state, State::Approved);
}

/// A reprocessed or corrected calibration keeps its author: the one who
/// submitted the measurement (and anyone who submitted a version of it
/// since) may not approve or reject the replacement, whoever submitted
/// the replacement; someone else may.
#[test]
fn authorship_survives_supersession() {
    let mut replacement = by("reprocessor", Some("Rita"));
    replacement.earlier = vec![
        ("corrector".into(), None),
        ("station".into(), Some("Ann".into())),
    ];
    for (signer, own) in [
        (principal("r2", Role::Reviewer, Some("Ann")), true),
        (principal("station", Role::Admin, None), true),
        (principal("corrector", Role::Reviewer, Some("Cy")), true),
        (principal("r3", Role::Reviewer, Some("Rita")), true),
        (principal("r4", Role::Reviewer, Some("Bob")), false),
        (principal("r5", Role::Reviewer, None), false),
    ] {
        let out = act(Action::Approve, signer.clone()).check(State::Submitted, &replacement, 1);
        assert_eq!(
            matches!(out, Err(Refusal::OwnWork { .. })),
            own,
            "{signer:?}: {out:?}"
        );
    }
    let e = act(
        Action::Approve,
        principal("r2", Role::Reviewer, Some("Ann")),
    )
    .check(State::Submitted, &replacement, 1)
    .unwrap_err();
    assert!(e.to_string().contains("(Ann)"), "{e}");
}

#[test]
fn bodies_say_what_is_missing_or_wrong() {
    let at = Timestamp::parse("2026-11-25T10:00:00Z").unwrap();
    let signer = principal("r", Role::Reviewer, None);
    let review = |json: serde_json::Value| {
        serde_json::from_value::<ReviewBody>(json)
            .unwrap()
            .act(signer.clone(), at)
    };
    let a = review(serde_json::json!({"decision": "approve"})).unwrap();
    assert_eq!((a.action, a.comment), (Action::Approve, None));
    let e = review(serde_json::json!({"decision": "reject"})).unwrap_err();
    assert_eq!(e.errors[0].pointer, "/comment");
    let a = review(serde_json::json!({"decision": "reject", "comment": "  drift  "})).unwrap();
    assert_eq!(a.comment.as_deref(), Some("drift"));
    let e = review(serde_json::json!({"decision": "reject", "comment": "   "})).unwrap_err();
    assert!(e.errors[0].detail.contains("empty"), "{e:?}");
    let long = "x".repeat(MAX_COMMENT_CHARS + 1);
    let e = review(serde_json::json!({"decision": "approve", "comment": long})).unwrap_err();
    assert!(e.errors[0].detail.contains("at most 2000"), "{e:?}");
    assert!(
        serde_json::from_value::<ReviewBody>(serde_json::json!({"decision": "maybe"})).is_err()
    );
    let w =
        serde_json::from_value::<WithdrawBody>(serde_json::json!({"reason": "wrong sensor id"}))
            .unwrap()
            .act(signer.clone(), at)
            .unwrap();
    assert_eq!(
        (w.action, w.comment.as_deref()),
        (Action::Withdraw, Some("wrong sensor id"))
    );
    let e = serde_json::from_value::<WithdrawBody>(serde_json::json!({"reason": ""}))
        .unwrap()
        .act(signer, at)
        .unwrap_err();
    assert_eq!(e.errors[0].pointer, "/reason");
}

#[test]
fn what_counts_on_each_basis() {
    use State::*;
    let all = [Submitted, Approved, Rejected, Withdrawn, Superseded];
    let not_rejected: Vec<bool> = all.iter().map(|s| s.counts(Basis::NotRejected)).collect();
    let approved: Vec<bool> = all.iter().map(|s| s.counts(Basis::ApprovedOnly)).collect();
    assert_eq!(not_rejected, [true, true, false, false, false]);
    assert_eq!(approved, [false, true, false, false, false]);
    for s in all {
        assert_eq!(State::parse(s.as_str()), Some(s));
    }
    assert_eq!(State::parse("deleted"), None);
}
