//! Triangulation and rigid-body fits (in progress on a helper branch).
