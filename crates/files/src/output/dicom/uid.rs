//! Deterministic DICOM UIDs: `2.25.<decimal>` where the decimal is a 128-bit UUID (RFC 9562
//! version 8, "custom") made from the SHA-256 of a label, so the same scenario, run, exposure,
//! detector and intent always get the same UID and the files stay byte-identical.
//!
//! The UUID is the first 16 bytes of `SHA-256(label)` (UTF-8), with the version nibble (the high
//! four bits of byte 6) set to `8` and the variant (the high two bits of byte 8) set to `10`,
//! read as a big-endian unsigned integer and written in decimal after `2.25.` (ITU-T X.667: a
//! UUID as an OID). The labels:
//!
//! - study: `rsasim/dicom/v1/study/{scenario_sha256}/{run}`
//! - series: `rsasim/dicom/v1/series/{scenario_sha256}/{run}/{exposure}/{intent}`
//! - instance: `rsasim/dicom/v1/instance/{scenario_sha256}/{run}/{exposure}/{detector}/{intent}`
//!
//! with the scenario file's SHA-256 in lowercase hex, the run id, the exposure and detector ids
//! verbatim and the intent `presentation` or `processing`. A stereo pair (one exposure, two
//! detectors) shares its study and series.

use sha2::{Digest, Sha256};

/// `2.25.<decimal>` of the version-8 UUID made from the SHA-256 of `label`.
pub fn uid_from_label(label: &str) -> String {
    let digest = Sha256::digest(label.as_bytes());
    let mut bytes = [0u8; 16];
    bytes.copy_from_slice(&digest[..16]);
    bytes[6] = (bytes[6] & 0x0f) | 0x80;
    bytes[8] = (bytes[8] & 0x3f) | 0x80;
    format!("2.25.{}", u128::from_be_bytes(bytes))
}

/// The Study Instance UID of a run (one exam), or of a dynamic exam's sequence (all its frames).
pub fn study_uid(scenario_sha256: &str, run: &str) -> String {
    uid_from_label(&format!("rsasim/dicom/v1/study/{scenario_sha256}/{run}"))
}

/// The Series Instance UID of one exposure's images of one intent in a run.
pub fn series_uid(scenario_sha256: &str, run: &str, exposure: &str, intent: &str) -> String {
    uid_from_label(&format!(
        "rsasim/dicom/v1/series/{scenario_sha256}/{run}/{exposure}/{intent}"
    ))
}

/// The Series Instance UID of one camera (`detector`) of `exposure` in a dynamic exam's `sequence`: its
/// frames, for `intent`.
pub fn camera_series_uid(
    scenario_sha256: &str,
    sequence: &str,
    exposure: &str,
    detector: &str,
    intent: &str,
) -> String {
    uid_from_label(&format!(
        "rsasim/dicom/v1/camera-series/{scenario_sha256}/{sequence}/{exposure}/{detector}/{intent}"
    ))
}

/// The SOP Instance UID of one image.
pub fn instance_uid(
    scenario_sha256: &str,
    run: &str,
    exposure: &str,
    detector: &str,
    intent: &str,
) -> String {
    uid_from_label(&format!(
        "rsasim/dicom/v1/instance/{scenario_sha256}/{run}/{exposure}/{detector}/{intent}"
    ))
}

/// The Implementation Class UID of the file meta header: rsasim's own, the UID of the label
/// `rsasim/dicom/v1/implementation`.
pub fn implementation_class_uid() -> String {
    uid_from_label("rsasim/dicom/v1/implementation")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valid UID: at most 64 characters, components of digits without leading zeros.
    fn valid_uid(uid: &str) -> bool {
        uid.len() <= 64
            && uid.split('.').all(|c| {
                !c.is_empty()
                    && c.bytes().all(|b| b.is_ascii_digit())
                    && (c == "0" || !c.starts_with('0'))
            })
    }

    #[test]
    fn uid_is_the_hand_computed_uuid() {
        // SHA-256("abc") = ba7816bf 8f01cfea 414140de 5dae2223 b00361a3 96177a9c b410ff61 f20015ad.
        // Bytes 0..16 with version 8 in byte 6 (0xcf → 0x8f) and variant 10 in byte 8
        // (0x41 → 0x81): ba7816bf 8f018fea 814140de 5dae2223.
        let want = u128::from_str_radix("ba7816bf8f018fea814140de5dae2223", 16).unwrap();
        assert_eq!(uid_from_label("abc"), format!("2.25.{want}"));
    }

    #[test]
    fn uids_are_valid_distinct_and_stable() {
        let sha = "0".repeat(64);
        let uids = [
            study_uid(&sha, "n0-r00"),
            study_uid(&sha, "n0-r01"),
            series_uid(&sha, "n0-r00", "ap", "presentation"),
            series_uid(&sha, "n0-r00", "ap", "processing"),
            instance_uid(&sha, "n0-r00", "ap", "det1", "presentation"),
            instance_uid(&sha, "n0-r00", "ap", "det2", "presentation"),
            implementation_class_uid(),
        ];
        for (i, u) in uids.iter().enumerate() {
            assert!(valid_uid(u), "{u}");
            assert!(!uids[..i].contains(u), "{u} repeats");
        }
        assert_eq!(study_uid(&sha, "n0-r00"), uids[0]);
        assert_eq!(
            instance_uid(&sha, "n0-r00", "ap", "det1", "presentation"),
            uid_from_label(&format!(
                "rsasim/dicom/v1/instance/{sha}/n0-r00/ap/det1/presentation"
            ))
        );
    }
}
