use super::*;
use dicom_object::from_reader;

fn image(intent: DicomIntent, meaning: PixelMeaning, pixels: &[u16]) -> DxImage<'_> {
    DxImage {
        intent,
        width: 5,
        height: 3,
        pixels,
        bits_stored: 12,
        meaning,
        pixel_pitch_mm: [0.3, 0.25],
        sid_mm: Some(1800.0),
        sod_mm: Some(1200.0),
        patient_orientation: Some(["L".into(), "F".into()]),
        kvp: Some(80.0),
        mas: Some(2.5),
        focal_spot_mm: None,
        detector_type: "",
        date: "20000101".into(),
        study_uid: uid::study_uid("ab", "n0-r00"),
        series_uid: uid::series_uid("ab", "n0-r00", "ap", intent.name()),
        instance_uid: uid::instance_uid("ab", "n0-r00", "ap", "det1", intent.name()),
        series_number: 1,
        instance_number: 2,
        acquisition_time: "000000".into(),
        patient_id: "test".into(),
        study_id: "n0-r00".into(),
        study_description: "rsasim run n0-r00".into(),
        series_description: "ap presentation".into(),
        detector_id: "det1".into(),
        comments: "a test".into(),
        software: "rsasim test".into(),
    }
}

fn read(bytes: &[u8]) -> dicom_object::DefaultDicomObject {
    assert_eq!(&bytes[..128], &[0u8; 128][..], "preamble");
    assert_eq!(&bytes[128..132], b"DICM");
    from_reader(&bytes[128..]).unwrap()
}

fn string(obj: &dicom_object::DefaultDicomObject, tag: Tag) -> String {
    obj.element(tag)
        .unwrap()
        .to_str()
        .unwrap()
        .trim_end()
        .to_string()
}

#[test]
fn round_trip_of_pixels_spacing_and_distances() {
    let pixels: Vec<u16> = (0..15).map(|k| k * 273).collect();
    let img = image(DicomIntent::Presentation, PixelMeaning::Linear, &pixels);
    let bytes = encode_dx(&img).unwrap();
    assert_eq!(bytes, encode_dx(&img).unwrap(), "two encodes differ");
    let obj = read(&bytes);
    assert_eq!(
        obj.meta()
            .media_storage_sop_class_uid()
            .trim_end_matches('\0'),
        "1.2.840.10008.5.1.4.1.1.1.1"
    );
    assert_eq!(obj.element(tags::ROWS).unwrap().to_int::<u16>().unwrap(), 3);
    assert_eq!(
        obj.element(tags::COLUMNS).unwrap().to_int::<u16>().unwrap(),
        5
    );
    assert_eq!(
        obj.element(tags::BITS_STORED)
            .unwrap()
            .to_int::<u16>()
            .unwrap(),
        12
    );
    assert_eq!(
        obj.element(tags::HIGH_BIT)
            .unwrap()
            .to_int::<u16>()
            .unwrap(),
        11
    );
    // Row spacing (the y pitch) first.
    assert_eq!(
        obj.element(tags::IMAGER_PIXEL_SPACING)
            .unwrap()
            .to_multi_float64()
            .unwrap(),
        [0.25, 0.3]
    );
    assert_eq!(
        obj.element(tags::PIXEL_SPACING)
            .unwrap()
            .to_multi_float64()
            .unwrap(),
        [0.25, 0.3]
    );
    let float = |tag| obj.element(tag).unwrap().to_float64().unwrap();
    assert_eq!(float(tags::DISTANCE_SOURCE_TO_DETECTOR), 1800.0);
    assert_eq!(float(tags::DISTANCE_SOURCE_TO_PATIENT), 1200.0);
    assert_eq!(
        float(tags::ESTIMATED_RADIOGRAPHIC_MAGNIFICATION_FACTOR),
        1.5
    );
    assert_eq!(float(tags::KVP), 80.0);
    assert_eq!(string(&obj, tags::EXPOSURE_INU_AS), "2500");
    // The 4096 values 0..=4095: a window of width 4096 centred at 2048.
    assert_eq!(float(tags::WINDOW_CENTER), 2048.0);
    assert_eq!(float(tags::WINDOW_WIDTH), 4096.0);
    assert_eq!(
        string(&obj, tags::PHOTOMETRIC_INTERPRETATION),
        "MONOCHROME1"
    );
    assert_eq!(string(&obj, tags::PRESENTATION_LUT_SHAPE), "INVERSE");
    assert_eq!(string(&obj, tags::PIXEL_INTENSITY_RELATIONSHIP), "LIN");
    assert_eq!(
        string(&obj, tags::PRESENTATION_INTENT_TYPE),
        "FOR PRESENTATION"
    );
    assert_eq!(string(&obj, tags::PATIENT_NAME), PATIENT_NAME);
    assert_eq!(string(&obj, tags::STUDY_DATE), "20000101");
    let raw = obj.element(tags::PIXEL_DATA).unwrap().to_bytes().unwrap();
    let back: Vec<u16> = raw
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    assert_eq!(back, pixels);
}

#[test]
fn intents_and_meanings_set_class_window_and_polarity() {
    let pixels = [7u16; 15];
    let processing =
        encode_dx(&image(DicomIntent::Processing, PixelMeaning::Log, &pixels)).unwrap();
    let obj = read(&processing);
    assert_eq!(
        string(&obj, tags::SOP_CLASS_UID).trim_end_matches('\0'),
        "1.2.840.10008.5.1.4.1.1.1.1.1"
    );
    assert_eq!(
        string(&obj, tags::PRESENTATION_INTENT_TYPE),
        "FOR PROCESSING"
    );
    assert!(obj.element(tags::WINDOW_CENTER).is_err(), "no window");
    assert_eq!(string(&obj, tags::PIXEL_INTENSITY_RELATIONSHIP), "LOG");
    assert_eq!(
        obj.element(tags::PIXEL_INTENSITY_RELATIONSHIP_SIGN)
            .unwrap()
            .to_int::<i16>()
            .unwrap(),
        -1
    );
    assert_eq!(
        string(&obj, tags::PHOTOMETRIC_INTERPRETATION),
        "MONOCHROME2"
    );
    let binary = encode_dx(&image(
        DicomIntent::Presentation,
        PixelMeaning::Silhouette,
        &pixels,
    ))
    .unwrap();
    let obj = read(&binary);
    assert_eq!(string(&obj, tags::PRESENTATION_LUT_SHAPE), "IDENTITY");
    assert_eq!(string(&obj, tags::PIXEL_INTENSITY_RELATIONSHIP), "LIN");
}

#[test]
fn optional_attributes_are_left_out_without_their_facts() {
    let pixels = [0u16; 15];
    let mut img = image(DicomIntent::Presentation, PixelMeaning::Silhouette, &pixels);
    img.kvp = None;
    img.mas = None;
    img.sod_mm = None;
    let obj = read(&encode_dx(&img).unwrap());
    for tag in [
        tags::KVP,
        tags::EXPOSURE,
        tags::EXPOSURE_INU_AS,
        tags::DISTANCE_SOURCE_TO_PATIENT,
        tags::ESTIMATED_RADIOGRAPHIC_MAGNIFICATION_FACTOR,
        tags::FOCAL_SPOTS,
    ] {
        assert!(obj.element(tag).is_err(), "{tag} present");
    }
    assert!(obj.element(tags::DISTANCE_SOURCE_TO_DETECTOR).is_ok());
}

#[test]
fn rejects_bad_input() {
    let pixels = [0u16; 15];
    let mut img = image(DicomIntent::Presentation, PixelMeaning::Linear, &pixels);
    img.width = 4;
    assert!(encode_dx(&img).is_err());
    img.width = 5;
    img.bits_stored = 5;
    assert!(encode_dx(&img).is_err());
    img.bits_stored = 17;
    assert!(encode_dx(&img).is_err());
}

#[test]
fn decimal_strings_fit_sixteen_characters() {
    assert_eq!(ds(1800.0), "1800");
    assert_eq!(ds(0.3), "0.3");
    assert_eq!(ds(430.0 / 1440.0), "0.29861111111111");
    assert_eq!(ds(-1234.5678901234567), "-1234.5678901235");
    assert_eq!(ds(1e6 / 3.0), "333333.333333333");
    for v in [
        1e-9,
        123456.789012345678,
        -0.000123456789123,
        999999.999999999,
    ] {
        let s = ds(v);
        assert!(s.len() <= 16, "{s}");
        let back: f64 = s.parse().unwrap();
        assert!((back - v).abs() <= 1e-9 * v.abs().max(1.0), "{v} → {s}");
    }
}
