//! `accelcal dcc verify`: a Digital Calibration Certificate's signature
//! checked offline, as a receiver would (issue 46).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::domain::dcc_signature::{Trust, verify};

/// Checks `file`'s signature, trusting the certificates in `certs` (PEM;
/// none: the certificate the file embeds). Prints who signed it and when
/// and exits 0, or prints why not and exits 1; 2 when a file cannot be read
/// or is not a DCC.
pub fn verify_file(file: &Path, certs: &[PathBuf]) -> ExitCode {
    let read = |p: &Path| std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()));
    let run = || -> Result<bool, String> {
        let bytes = read(file)?;
        let text = std::str::from_utf8(&bytes)
            .map_err(|e| format!("{}: not UTF-8: {e}", file.display()))?;
        let pems = certs
            .iter()
            .map(|c| read(c))
            .collect::<Result<Vec<_>, _>>()?;
        let trust = if pems.is_empty() {
            Trust::Embedded
        } else {
            Trust::Certificates(&pems)
        };
        let v = verify(text, &trust).map_err(|e| format!("{}: not a DCC: {e}", file.display()))?;
        println!("file: {}", file.display());
        println!("sha256: {}", v.sha256);
        if let Some(s) = &v.signer {
            println!("signer: {}", s.subject);
            println!("signer issued by: {}", s.issuer);
            println!("signer certificate sha256: {}", s.sha256);
            println!(
                "signer certificate valid: {} to {}",
                s.not_before, s.not_after
            );
        }
        if let Some(t) = &v.signing_time {
            println!("signed at: {t}");
        }
        println!(
            "trusted: {}",
            match trust {
                Trust::Embedded =>
                    "the certificate the file embeds (name one with --cert to trust only it)",
                Trust::Certificates(_) => "the certificates given with --cert",
            }
        );
        match &v.reason {
            None => println!("valid: yes"),
            Some(why) => {
                println!("valid: no");
                eprintln!(
                    "accelcal: {}: the signature does not hold: {why}",
                    file.display()
                );
            }
        }
        Ok(v.valid)
    };
    match run() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("accelcal: {e}");
            ExitCode::from(2)
        }
    }
}
