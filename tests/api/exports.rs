//! Exports carry numbers, never code (issue 43 item 1): hostile text in
//! every field an export writes (the unit, the source line with the sensor
//! id) goes through every format; the C header compiles with `-Wall
//! -Werror` (trigraphs on), defines exactly the documented symbols and
//! gives the text back byte for byte; the parameter files parse to exactly
//! the documented parameters; JSON keeps the text as sent.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use accelcal::domain::triad_export::{C_SYMBOLS, Exported, Format, export};
use proptest::prelude::*;
use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

/// What an export of `unit` and `source` holds, the numbers fixed.
fn exported<'a>(unit: &'a str, source: &str, s2: bool) -> Exported<'a> {
    Exported {
        unit,
        b: [0.125, -0.25, 0.375],
        s: [[9.8, 0.0, 0.0], [0.0098, 9.9, 0.0], [0.0, 0.0, 9.7]],
        t: [
            [1.0 / 9.8, 0.0, 0.0],
            [-0.0098 / (9.8 * 9.9), 1.0 / 9.9, 0.0],
            [0.0, 0.0, 1.0 / 9.7],
        ],
        s2: s2.then_some([1e-3, -2e-3, 0.0]),
        source: source.to_owned(),
    }
}

/// The identifiers of C source `code` outside its string literals (a
/// small tokenizer: comments are gone after the preprocessor).
fn identifiers(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut chars = code.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '"' {
            while let Some(d) = chars.next() {
                match d {
                    '\\' => {
                        chars.next();
                    }
                    '"' => break,
                    _ => {}
                }
            }
        } else if c.is_ascii_digit() {
            let mut prev = c;
            while let Some(&d) = chars.peek() {
                let exponent_sign = matches!(d, '+' | '-') && matches!(prev, 'e' | 'E');
                if d.is_ascii_alphanumeric() || d == '.' || exponent_sign {
                    prev = d;
                    chars.next();
                } else {
                    break;
                }
            }
        } else if c.is_ascii_alphabetic() || c == '_' {
            let mut id = String::from(c);
            while let Some(&d) = chars.peek() {
                if d.is_ascii_alphanumeric() || d == '_' {
                    id.push(d);
                    chars.next();
                } else {
                    break;
                }
            }
            out.insert(id);
        }
    }
    out
}

fn run(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().expect("a C compiler (cc) on PATH");
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

const MAIN_C: &str = r#"#include <stdio.h>
#include "accelcal_triad.h"
int main(void) {
    printf("%zu ", sizeof ACCELCAL_SOURCE - 1);
    fwrite(ACCELCAL_SOURCE, 1, sizeof ACCELCAL_SOURCE - 1, stdout);
    printf("%zu ", sizeof ACCELCAL_UNIT - 1);
    fwrite(ACCELCAL_UNIT, 1, sizeof ACCELCAL_UNIT - 1, stdout);
    printf("%.12e %.12e %.12e", ACCELCAL_B[0], ACCELCAL_S[1][0], ACCELCAL_T[1][0]);
#ifdef WITH_S2
    printf(" %.12e", ACCELCAL_S2[1]);
#endif
    return 0;
}
"#;

/// Compiles `header` with a program that uses every symbol, in `dir`;
/// checks the symbols it declares and the text it gives back.
fn check_c_header(dir: &Path, header: &str, e: &Exported<'_>) {
    std::fs::write(dir.join("accelcal_triad.h"), header).unwrap();
    std::fs::write(dir.join("main.c"), MAIN_C).unwrap();
    // Exactly the documented declarations, after the preprocessor.
    let pre = run(Command::new("cc")
        .args(["-std=c11", "-trigraphs", "-E", "-P", "-x", "c"])
        .arg(dir.join("accelcal_triad.h")));
    let ids = identifiers(&String::from_utf8(pre.stdout).unwrap());
    let mut want: BTreeSet<String> = ["static", "const", "char", "double"]
        .map(String::from)
        .into();
    let n = if e.s2.is_some() { 6 } else { 5 };
    want.extend(C_SYMBOLS[..n].iter().map(|s| s.to_string()));
    assert_eq!(ids, want, "{header}");
    // Exactly one macro: the include guard.
    let macros = |path: &Path| -> BTreeSet<String> {
        let out = run(Command::new("cc")
            .args(["-std=c11", "-trigraphs", "-dM", "-E", "-x", "c"])
            .arg(path));
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(str::to_owned)
            .collect()
    };
    std::fs::write(dir.join("empty.h"), "").unwrap();
    let added: Vec<String> = macros(&dir.join("accelcal_triad.h"))
        .difference(&macros(&dir.join("empty.h")))
        .cloned()
        .collect();
    assert_eq!(added, ["#define ACCELCAL_TRIAD_H "], "{header}");
    // Compiles clean, and gives the text and the numbers back.
    let exe = dir.join("main");
    let mut cc = Command::new("cc");
    cc.args([
        "-std=c11",
        "-trigraphs",
        "-Wall",
        "-Wextra",
        "-Werror",
        "-pedantic",
    ]);
    if e.s2.is_some() {
        cc.arg("-DWITH_S2");
    }
    run(cc
        .arg("-I")
        .arg(dir)
        .arg(dir.join("main.c"))
        .arg("-o")
        .arg(&exe));
    let out = run(&mut Command::new(&exe)).stdout;
    // Each string as its length, a space and its bytes; then the numbers.
    let mut rest = &out[..];
    let mut string = || {
        let space = rest.iter().position(|b| *b == b' ').unwrap();
        let n: usize = std::str::from_utf8(&rest[..space])
            .unwrap()
            .parse()
            .unwrap();
        let s = rest[space + 1..space + 1 + n].to_vec();
        rest = &rest[space + 1 + n..];
        s
    };
    assert_eq!(string(), e.source.as_bytes());
    assert_eq!(string(), e.unit.as_bytes());
    let mut numbers = format!("{:.12e} {:.12e} {:.12e}", e.b[0], e.s[1][0], e.t[1][0]);
    if let Some(s2) = e.s2 {
        numbers += &format!(" {:.12e}", s2[1]);
    }
    // C's %e writes the exponent with a sign and two digits.
    let c_style = |s: &str| -> String {
        s.split(' ')
            .map(|x| {
                let (m, e) = x.split_once('e').unwrap();
                let e: i32 = e.parse().unwrap();
                format!("{m}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
            })
            .collect::<Vec<_>>()
            .join(" ")
    };
    assert_eq!(String::from_utf8(rest.to_vec()).unwrap(), c_style(&numbers));
}

/// A parameter file's parameters: `NAME → value`, every line either a `#`
/// comment or one parameter in the format's own shape.
fn parameters(text: &str, format: Format) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with('#') {
            continue;
        }
        let (name, value) = match format {
            Format::Px4 => {
                let f: Vec<&str> = line.split('\t').collect();
                assert_eq!(f.len(), 5, "{line:?}");
                assert_eq!((f[0], f[1], f[4]), ("1", "1", "9"), "{line:?}");
                (f[2], f[3])
            }
            _ => line.split_once(',').unwrap_or_else(|| panic!("{line:?}")),
        };
        out.push((name.to_owned(), value.parse().unwrap()));
    }
    out
}

/// Strings meant to break out of a comment, a string, a line or a parser.
fn hostile() -> impl Strategy<Value = String> {
    let pieces = prop::sample::select(vec![
        "*/",
        "/*",
        "//",
        "\\",
        "\n",
        "\r",
        "\"",
        "'",
        "??/",
        "??=",
        "?",
        "#",
        "#define X 1",
        "int accelcal_pwn=1;",
        "\t",
        ",",
        "é",
        "€",
        "\u{2028}",
        "\u{feff}",
        "\0",
        "%s",
        "g",
        "m/s2",
        "\u{10ffff}",
        "\\u{41}",
    ]);
    prop_oneof![
        prop::collection::vec(pieces, 0..8).prop_map(|p| p.concat()),
        any::<String>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Whatever the unit and the source hold, every format carries the
    /// numbers and nothing else.
    #[test]
    fn hostile_text_never_becomes_code(unit in hostile(), source in hostile(), s2: bool) {
        let dir = tempfile::tempdir().unwrap();
        let e = exported(&unit, &source, s2);
        check_c_header(dir.path(), &export(&e, Format::C).unwrap(), &e);
        let v: Value = serde_json::from_str(&export(&e, Format::Json).unwrap()).unwrap();
        prop_assert_eq!(v["unit"].as_str().unwrap(), unit.as_str());
        prop_assert_eq!(v["source"].as_str().unwrap(), source.as_str());
        // The diagonal formats take m/s2 or g only: the unit is one of
        // those, the source is free.
        for unit in ["m/s2", "g"] {
            let e = exported(unit, &source, false);
            for (format, names) in [
                (Format::Px4, ["CAL_ACC0_XOFF", "CAL_ACC0_YOFF", "CAL_ACC0_ZOFF",
                    "CAL_ACC0_XSCALE", "CAL_ACC0_YSCALE", "CAL_ACC0_ZSCALE"]),
                (Format::ArduPilot, ["INS_ACCOFFS_X", "INS_ACCOFFS_Y", "INS_ACCOFFS_Z",
                    "INS_ACCSCAL_X", "INS_ACCSCAL_Y", "INS_ACCSCAL_Z"]),
            ] {
                let text = export(&e, format).unwrap();
                let got = parameters(&text, format);
                let got_names: Vec<&str> = got.iter().map(|(n, _)| n.as_str()).collect();
                prop_assert_eq!(&got_names[..], &names[..], "{}", text);
                let per = if unit == "g" { 9.80665 } else { 1.0 };
                prop_assert!((got[1].1 - e.b[1] * per).abs() < 1e-9, "{}", text);
            }
        }
    }
}

/// The issue's own case, end to end: a unit that closes the header's
/// comment, on the computed and on the stored triad's export.
#[tokio::test]
async fn a_unit_that_closes_a_comment_stays_text() {
    let app = TestApp::spawn(Sqlite).await;
    let mut body = crate::triad::known_body();
    let unit = "g*/int accelcal_pwn=1;/*";
    body["unit"] = json!(unit);
    let res = app.post("/v1/identify/triad?export=c", ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::OK);
    let computed = res.text().await.unwrap();
    let stored: Value = app
        .post("/v1/calibrations/triad", ADMIN, &body)
        .await
        .json()
        .await
        .unwrap();
    let id = stored["id"].as_str().unwrap_or_else(|| panic!("{stored}"));
    let res = app
        .get(&format!("/v1/calibrations/{id}/export?format=c"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let from_store = res.text().await.unwrap();
    for header in [computed, from_store] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("accelcal_triad.h"), &header).unwrap();
        let pre = run(Command::new("cc")
            .args(["-std=c11", "-trigraphs", "-E", "-P", "-x", "c"])
            .arg(dir.path().join("accelcal_triad.h")));
        let ids = identifiers(&String::from_utf8(pre.stdout).unwrap());
        assert!(!ids.contains("accelcal_pwn"), "{header}");
        assert!(
            header.contains(r#"ACCELCAL_UNIT[] = "g*/int accelcal_pwn=1;/*";"#),
            "{header}"
        );
    }
}
