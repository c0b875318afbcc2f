//! Connecting: the URL, TLS and the pool.
//!
//! The URL is libpq's (`postgres://user:password@host:port/db?sslmode=…`),
//! read by tokio-postgres, plus one parameter of accelcal's own:
//! `sslrootcert=/path/ca.pem`. TLS (rustls) follows `sslmode`:
//!
//! * `disable` — none; `prefer` (the default) — TLS when the server offers
//!   it; `require` — TLS or no connection. Like libpq, these encrypt without
//!   authenticating the server;
//! * with `sslrootcert`, the server's certificate must chain to that CA and
//!   name the host (libpq's `verify-full`).
//!
//! Every connection is opened with `synchronous_commit=on` (whatever the
//! server's default: a commit returns only once it is durable) and
//! `application_name=accelcal`.

use std::sync::Arc;
use std::time::Duration;

use deadpool_postgres::{Manager, ManagerConfig, Pool, RecyclingMethod, Runtime};
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{ClientConfig, DigitallySignedStruct, RootCertStore, SignatureScheme};
use tokio_postgres_rustls::MakeRustlsConnect;

use crate::store::StoreError;

/// Connections in the pool at most (per replica).
pub const POOL_SIZE: usize = 16;
/// How long a request waits for a connection, or for one to be opened.
const WAIT: Duration = Duration::from_secs(5);

fn refused(why: impl Into<String>) -> StoreError {
    StoreError::Unavailable(why.into().into())
}

/// Splits accelcal's own `sslrootcert` parameter off a URL.
pub fn split_root_cert(url: &str) -> (String, Option<String>) {
    let Some((base, query)) = url.split_once('?') else {
        return (url.to_owned(), None);
    };
    let mut root = None;
    let kept: Vec<&str> = query
        .split('&')
        .filter(|pair| match pair.split_once('=') {
            Some(("sslrootcert", path)) => {
                root = Some(path.to_owned());
                false
            }
            _ => true,
        })
        .collect();
    let url = if kept.is_empty() {
        base.to_owned()
    } else {
        format!("{base}?{}", kept.join("&"))
    };
    (url, root)
}

/// Accepts any server certificate but checks the handshake's signatures:
/// libpq's `sslmode=require` (encryption, no authentication).
#[derive(Debug)]
struct EncryptOnly(Arc<rustls::crypto::CryptoProvider>);

impl ServerCertVerifier for EncryptOnly {
    fn verify_server_cert(
        &self,
        _: &CertificateDer<'_>,
        _: &[CertificateDer<'_>],
        _: &ServerName<'_>,
        _: &[u8],
        _: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        Ok(ServerCertVerified::assertion())
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(
            message,
            cert,
            dss,
            &self.0.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(
            message,
            cert,
            dss,
            &self.0.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.0.signature_verification_algorithms.supported_schemes()
    }
}

fn tls(root_cert: Option<&str>) -> Result<MakeRustlsConnect, StoreError> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = ClientConfig::builder_with_provider(provider.clone())
        .with_safe_default_protocol_versions()
        .map_err(|e| refused(format!("TLS: {e}")))?;
    let config = match root_cert {
        Some(path) => {
            let pem =
                std::fs::read(path).map_err(|e| refused(format!("sslrootcert {path}: {e}")))?;
            let mut roots = RootCertStore::empty();
            for cert in rustls_pemfile_certs(&pem)? {
                roots
                    .add(cert)
                    .map_err(|e| refused(format!("sslrootcert {path}: {e}")))?;
            }
            builder.with_root_certificates(roots).with_no_client_auth()
        }
        None => builder
            .dangerous()
            .with_custom_certificate_verifier(Arc::new(EncryptOnly(provider)))
            .with_no_client_auth(),
    };
    Ok(MakeRustlsConnect::new(config))
}

/// The certificates of a PEM file.
fn rustls_pemfile_certs(pem: &[u8]) -> Result<Vec<CertificateDer<'static>>, StoreError> {
    use rustls::pki_types::pem::PemObject;
    CertificateDer::pem_slice_iter(pem)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| refused(format!("sslrootcert: {e}")))
}

/// The connection settings and TLS connector for `url`, as every
/// connection of accelcal's uses them (the pool's and the listener's).
pub fn config(url: &str) -> Result<(tokio_postgres::Config, MakeRustlsConnect), StoreError> {
    let (url, root_cert) = split_root_cert(url);
    let mut config: tokio_postgres::Config = url
        .parse()
        .map_err(|e| refused(format!("the PostgreSQL URL does not parse: {e}")))?;
    let options = config.get_options().map(str::to_owned);
    config.options(format!(
        "{} -c synchronous_commit=on",
        options.unwrap_or_default()
    ));
    if config.get_application_name().is_none() {
        config.application_name("accelcal");
    }
    if config.get_connect_timeout().is_none() {
        config.connect_timeout(WAIT);
    }
    Ok((config, tls(root_cert.as_deref())?))
}

/// The pool for `url` (no connection is opened yet).
pub fn pool(url: &str) -> Result<Pool, StoreError> {
    let (config, tls) = config(url)?;
    let manager = Manager::from_config(
        config,
        tls,
        ManagerConfig {
            recycling_method: RecyclingMethod::Fast,
        },
    );
    Pool::builder(manager)
        .max_size(POOL_SIZE)
        .runtime(Runtime::Tokio1)
        .wait_timeout(Some(WAIT))
        .create_timeout(Some(WAIT))
        .recycle_timeout(Some(WAIT))
        .build()
        .map_err(|e| refused(format!("the connection pool: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_root_certificate_parameter_is_ours() {
        assert_eq!(
            split_root_cert("postgres://u@h/db?sslmode=require&sslrootcert=/ca.pem"),
            (
                "postgres://u@h/db?sslmode=require".into(),
                Some("/ca.pem".into())
            )
        );
        assert_eq!(
            split_root_cert("postgres://u@h/db?sslrootcert=/ca.pem"),
            ("postgres://u@h/db".into(), Some("/ca.pem".into()))
        );
        assert_eq!(
            split_root_cert("postgres://u@h/db"),
            ("postgres://u@h/db".into(), None)
        );
    }
}
