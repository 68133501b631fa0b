//! Why a world was refused: [`WorldError`], naming the file, the line and the key.

use std::path::PathBuf;

use thiserror::Error;

use super::mesh_file::MeshError;

/// Why a world was refused. The server does not start with a world that fails here.
#[derive(Debug, Error)]
pub enum WorldError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Read {
        /// World file.
        file: PathBuf,
        /// The I/O error.
        message: String,
    },
    /// TOML syntax, an unknown key, a missing key or a wrong type.
    #[error("{file}:{line}: {message}")]
    Syntax {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// What the TOML parser reported (it names the key).
        message: String,
    },
    /// A value out of its domain.
    #[error("{file}:{line}: `{key}`: {message}")]
    Invalid {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// Dotted key, e.g. `objects[0].material.stiffness_n_per_mm`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A mesh file that is missing, unreadable or not a valid surface.
    #[error("{file}:{line}: `{key}` = {mesh:?}: {reason}")]
    Mesh {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// Dotted key of the mesh entry.
        key: String,
        /// Mesh path as written.
        mesh: String,
        /// What is wrong with it.
        reason: MeshError,
    },
}
