//! Scene calibration (in progress on a helper branch).
