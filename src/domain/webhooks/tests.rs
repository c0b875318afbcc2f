use std::time::Duration;

use super::*;

/// Standard Webhooks' own example (the specification's and Svix's docs),
/// and a second computed with Python's `hmac` — not by this code.
#[test]
fn signatures_match_the_specification() {
    let s = Secret::parse("whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw").unwrap();
    assert_eq!(
        signature(
            &s,
            "msg_p5jXN8AQM9LWM0D4loKWxJek",
            1614265330,
            br#"{"test": 2432232314}"#
        ),
        "v1,g0hM9SsE+OTPJTGt/tmIKtSyZlE3uFJELVlNIOLJ1OE="
    );
    let abc = Secret::parse("whsec_QUJDREVGR0hJSktMTU5PUFFSU1RVVldYWVo=").unwrap();
    assert_eq!(
        signature(&abc, "evt_7", 1_700_000_000, b"{}"),
        "v1,O4ts/2OUw4I3qAjaY0d0Q3lkig5Z987dB0ea+xDK9D4="
    );
}

/// Both secrets sign during the overlap, the current first; after it only
/// the current.
#[test]
fn a_rotated_secret_signs_until_its_overlap_ends() {
    let old = Secret::parse("whsec_QUJDREVGR0hJSktMTU5PUFFSU1RVVldYWVo=").unwrap();
    let new = Secret::generate().unwrap();
    let until = Timestamp::parse("2026-11-28T12:00:00Z").unwrap();
    let s = Secrets {
        current: new.clone(),
        previous: Some((old.clone(), until)),
    };
    let during = s.header(until.plus_seconds(-1), "evt_7", 1_700_000_000, b"{}");
    assert_eq!(
        during,
        format!(
            "{} v1,O4ts/2OUw4I3qAjaY0d0Q3lkig5Z987dB0ea+xDK9D4=",
            signature(&new, "evt_7", 1_700_000_000, b"{}")
        )
    );
    let after = s.header(until, "evt_7", 1_700_000_000, b"{}");
    assert_eq!(after, signature(&new, "evt_7", 1_700_000_000, b"{}"));
}

#[test]
fn generated_secrets_parse_and_hide() {
    let a = Secret::generate().unwrap();
    let b = Secret::generate().unwrap();
    assert_ne!(a, b);
    assert!(a.expose().starts_with("whsec_"));
    assert_eq!(Secret::parse(a.expose()).unwrap(), a);
    assert_eq!(a.key().len(), KEY_BYTES);
    assert_eq!(format!("{a:?}"), "Secret(..)");
    assert!(Secret::parse("whsec_").is_none());
    assert!(Secret::parse("whsec_not base64!").is_none());
    assert!(Secret::parse("QUJD").is_none());
}

/// The schedule the issue states: 5 s doubling to a 1 h cap, ±20 %.
#[test]
fn delays_double_to_the_cap_within_the_jitter() {
    let r = Retry {
        base: Duration::from_secs(5),
        cap: Duration::from_secs(3600),
        max_age: Duration::from_secs(3 * 86400),
    };
    let mid: Vec<u64> = (1..=12).map(|n| r.delay(n, 0.5).as_secs()).collect();
    assert_eq!(
        mid,
        [5, 10, 20, 40, 80, 160, 320, 640, 1280, 2560, 3600, 3600]
    );
    assert_eq!(r.delay(1, 0.0), Duration::from_secs(4));
    assert_eq!(r.delay(1, 1.0), Duration::from_secs(6));
    assert_eq!(r.delay(40, 0.0), Duration::from_secs(2880));
    let at = Timestamp::parse("2026-11-25T12:00:00Z").unwrap();
    assert!(!r.expired(at, Timestamp::parse("2026-11-28T12:00:00Z").unwrap()));
    assert!(r.expired(at, Timestamp::parse("2026-11-28T12:00:01Z").unwrap()));
}

#[test]
fn addresses_that_are_refused() {
    for (ip, why) in [
        ("127.0.0.1", "loopback"),
        ("10.1.2.3", "private"),
        ("172.16.0.1", "private"),
        ("192.168.1.1", "private"),
        ("169.254.169.254", "link-local"),
        ("100.64.0.1", "shared (carrier-grade NAT)"),
        ("0.0.0.0", "unspecified"),
        ("224.0.0.1", "broadcast or multicast"),
        ("192.0.2.1", "reserved"),
        ("::1", "loopback"),
        ("::", "unspecified"),
        ("fd00::1", "private (unique local)"),
        ("fe80::1", "link-local"),
        ("::ffff:127.0.0.1", "loopback"),
        ("::ffff:10.0.0.1", "private"),
        ("2001:db8::1", "reserved"),
    ] {
        assert_eq!(refused_address(ip.parse().unwrap()), Some(why), "{ip}");
    }
    for ip in ["93.184.215.14", "8.8.8.8", "172.32.0.1", "2606:4700::1111"] {
        assert_eq!(refused_address(ip.parse().unwrap()), None, "{ip}");
    }
}

#[test]
fn bodies_are_checked_field_by_field() {
    let body: WebhookBody = serde_json::from_value(serde_json::json!({
        "url": "ftp://example.com/x",
        "sensors": ["ok", "not ok"],
        "event_types": ["calibration.stored"],
    }))
    .unwrap();
    let invalid = body.check("w".into()).unwrap_err();
    let text = format!("{invalid:?}");
    assert!(
        text.contains("/url") && text.contains("scheme `ftp`"),
        "{text}"
    );
    assert!(text.contains("/sensors/1"), "{text}");
    for (url, why) in [
        ("https://u:p@example.com/", "user name or password"),
        ("https://example.com/#x", "fragment"),
        ("not a url", "is not a URL"),
    ] {
        assert!(target(url).unwrap_err().contains(why), "{url}");
    }
    let body: WebhookBody = serde_json::from_value(serde_json::json!({
        "url": "https://Example.COM/hook",
        "sensors": ["B", "A", "B"],
        "event_types": ["calibration.held", "calibration.approved", "calibration.held"],
    }))
    .unwrap();
    let (def, _) = body.check("w".into()).unwrap();
    assert_eq!(def.url, "https://example.com/hook");
    assert_eq!(def.sensors, ["A", "B"]);
    assert_eq!(
        def.event_types,
        [EventType::CalibrationApproved, EventType::CalibrationHeld]
    );
}

/// JSON Schema's integers: `7` and `7.0` alike; `7.5` and `"7"` refused.
#[test]
fn integers_may_be_written_with_a_zero_fraction() {
    let r: RedeliverBody = serde_json::from_str(r#"{"after": 7.0}"#).unwrap();
    assert_eq!(r.after, 7);
    let r: RotateBody = serde_json::from_str(r#"{"overlap_s": 60}"#).unwrap();
    assert_eq!(r.overlap_s, Some(60));
    assert!(serde_json::from_str::<RedeliverBody>(r#"{"after": 7.5}"#).is_err());
    assert!(serde_json::from_str::<RedeliverBody>(r#"{"after": "7"}"#).is_err());
    for empty in ["{}", r#"{"overlap_s": null}"#] {
        let r: RotateBody = serde_json::from_str(empty).unwrap();
        assert_eq!(r.overlap_s, None);
    }
    let r: RotateBody = serde_json::from_str(r#"{"overlap_s": 60.0}"#).unwrap();
    assert_eq!(r.overlap_s, Some(60));
}
