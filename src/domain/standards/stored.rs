//! How standards were stored before accelcal kept parameters by
//! certificate: read as they are, an earlier certificate without its own
//! parameters takes the standard's current ones, marked
//! `parameters_assumed`.

use super::*;

#[derive(Deserialize)]
pub struct PeriodStored {
    certificate: StandardCertificate,
    due_at: Timestamp,
    #[serde(default)]
    angle_std_arcsec: Option<f64>,
    #[serde(default)]
    gravity_m_s2: Option<f64>,
    #[serde(default)]
    gravity_rel_std: Option<f64>,
    #[serde(default)]
    temperature_std_c: Option<f64>,
    #[serde(default)]
    degrees_of_freedom: Option<f64>,
    #[serde(default)]
    traceability: Option<String>,
    #[serde(default)]
    parameters_assumed: bool,
}

#[derive(Deserialize)]
pub struct StandardStored {
    standard_id: String,
    kind: StandardKind,
    description: String,
    manufacturer: Option<String>,
    model: Option<String>,
    serial: Option<String>,
    certificate: StandardCertificate,
    due_at: Timestamp,
    angle_std_arcsec: Option<f64>,
    gravity_m_s2: Option<f64>,
    gravity_rel_std: Option<f64>,
    temperature_std_c: Option<f64>,
    #[serde(default)]
    degrees_of_freedom: Option<f64>,
    traceability: String,
    #[serde(default)]
    earlier: Vec<PeriodStored>,
    updated_at: Timestamp,
}

impl From<StandardStored> for Standard {
    fn from(s: StandardStored) -> Standard {
        let mut standard = Standard {
            standard_id: s.standard_id,
            kind: s.kind,
            description: s.description,
            manufacturer: s.manufacturer,
            model: s.model,
            serial: s.serial,
            certificate: s.certificate,
            due_at: s.due_at,
            angle_std_arcsec: s.angle_std_arcsec,
            gravity_m_s2: s.gravity_m_s2,
            gravity_rel_std: s.gravity_rel_std,
            temperature_std_c: s.temperature_std_c,
            degrees_of_freedom: s.degrees_of_freedom,
            traceability: s.traceability,
            earlier: Vec::new(),
            updated_at: s.updated_at,
        };
        let today = standard.parameters();
        standard.earlier = s
            .earlier
            .into_iter()
            .map(|p| match p.traceability {
                Some(traceability) => CertificatePeriod {
                    certificate: p.certificate,
                    due_at: p.due_at,
                    parameters: Parameters {
                        angle_std_arcsec: p.angle_std_arcsec,
                        gravity_m_s2: p.gravity_m_s2,
                        gravity_rel_std: p.gravity_rel_std,
                        temperature_std_c: p.temperature_std_c,
                        degrees_of_freedom: p.degrees_of_freedom,
                        traceability,
                    },
                    parameters_assumed: p.parameters_assumed,
                },
                None => CertificatePeriod {
                    certificate: p.certificate,
                    due_at: p.due_at,
                    parameters: today.clone(),
                    parameters_assumed: true,
                },
            })
            .collect();
        standard
    }
}
