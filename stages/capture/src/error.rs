//! The error type of the capture crate.

use std::path::PathBuf;

/// Everything that can go wrong when loading objects, configuring views or
/// reading and writing label files. Messages name the file or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// A file could not be opened, read or written.
    #[error("cannot access {}: {cause}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// An OBJ file could not be parsed.
    #[error("cannot load OBJ mesh {}: {reason}", path.display())]
    Obj {
        /// The OBJ file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An MTL material library referenced by an OBJ file could not be loaded.
    #[error("cannot load material library {} (referenced by {}): {reason}", path.display(), obj.display())]
    Mtl {
        /// The MTL file.
        path: PathBuf,
        /// The OBJ file that references it.
        obj: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A mesh in an OBJ file has no texture coordinates (`vt`).
    #[error(
        "OBJ mesh {}: object '{mesh}' has no texture coordinates (vt); the renderer needs a UV-mapped, textured mesh",
        path.display()
    )]
    MissingTexCoords {
        /// The OBJ file.
        path: PathBuf,
        /// The name of the object/group without texture coordinates.
        mesh: String,
    },
    /// A mesh in an OBJ file has no diffuse texture (`map_Kd` in the MTL file).
    #[error(
        "OBJ mesh {}: object '{mesh}' has no diffuse texture ({detail}); the renderer needs a `map_Kd` texture",
        path.display()
    )]
    MissingTexture {
        /// The OBJ file.
        path: PathBuf,
        /// The name of the object/group.
        mesh: String,
        /// Which link is missing (no material, or a material without `map_Kd`).
        detail: String,
    },
    /// A texture image could not be opened or decoded.
    #[error("cannot load texture {}: {reason}", path.display())]
    Texture {
        /// The image file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A mesh file contains no triangles.
    #[error("mesh {} contains no triangles", path.display())]
    EmptyMesh {
        /// The mesh file.
        path: PathBuf,
    },
    /// A PLY file could not be parsed or describes no usable mesh.
    #[error("cannot load PLY mesh {}: {reason}", path.display())]
    Ply {
        /// The PLY file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A glTF 2.0 or GLB file could not be parsed or uses what the loader
    /// does not support.
    #[error("cannot load glTF mesh {}: {reason}", path.display())]
    Gltf {
        /// The .gltf or .glb file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A mesh (or a part of it) with nothing to colour it by.
    #[error("mesh {} has no colour: neither vertex colours nor a texture{detail}", path.display())]
    NoColour {
        /// The mesh file.
        path: PathBuf,
        /// Which part, or why a texture it names does not count; empty or
        /// starting with a space.
        detail: String,
    },
    /// A texture image named by a PLY or glTF mesh could not be loaded.
    #[error("cannot load texture {} (referenced by {}): {reason}", path.display(), mesh.display())]
    MeshTexture {
        /// The image file.
        path: PathBuf,
        /// The mesh file that names it.
        mesh: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A mesh file whose extension names no supported format.
    #[error("mesh {}: unknown mesh format (by its extension); accepted: {accepted}", path.display())]
    UnknownMeshFormat {
        /// The mesh file.
        path: PathBuf,
        /// The accepted extensions, comma separated.
        accepted: String,
    },
    /// An object that cannot be written as a PLY mesh.
    #[error("cannot write PLY mesh {}: {reason}", path.display())]
    PlyWrite {
        /// The PLY file to be written.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Elevation outside [0, 90] degrees.
    #[error("elevation theta = {value} deg is outside [0, 90]")]
    InvalidTheta {
        /// The offending value in degrees.
        value: f64,
    },
    /// Azimuth that is not a finite number.
    #[error("azimuth phi = {value} deg is not a finite number")]
    InvalidPhi {
        /// The offending value in degrees.
        value: f64,
    },
    /// Camera roll about the optical axis that is not a finite number.
    #[error("camera roll {value} deg is not a finite number")]
    InvalidRoll {
        /// The offending value in degrees.
        value: f64,
    },
    /// Camera distance that is not finite and positive.
    #[error("camera distance {value} must be a finite number > 0 (in object bounding radii)")]
    InvalidDistance {
        /// The offending value.
        value: f64,
    },
    /// Camera intrinsics that cannot describe a camera.
    #[error("invalid camera intrinsics: {reason}")]
    InvalidIntrinsics {
        /// What is wrong.
        reason: String,
    },
    /// Invalid trajectory parameters.
    #[error("invalid trajectory: {reason}")]
    InvalidTrajectory {
        /// What is wrong.
        reason: String,
    },
    /// A real size (an object radius, a mesh unit) that is not a positive
    /// number of metres.
    #[error("{what} must be a positive number of metres up to 1000, not {metres}")]
    InvalidSize {
        /// Which size.
        what: &'static str,
        /// The value given.
        metres: f64,
    },
    /// An unknown built-in object name.
    #[error("unknown object '{name}'; valid built-in objects: {valid}")]
    UnknownObject {
        /// The name asked for.
        name: String,
        /// The valid names, comma separated.
        valid: String,
    },
    /// An unknown background name.
    #[error("unknown background '{name}'; valid backgrounds: {valid}")]
    UnknownBackground {
        /// The name asked for.
        name: String,
        /// The valid names, comma separated.
        valid: String,
    },
    /// An unknown texture set name.
    #[error("unknown texture set '{name}'; valid: training, held-out")]
    UnknownTextureSet {
        /// The name asked for.
        name: String,
    },
    /// An unknown up-axis name.
    #[error("unknown up axis '{name}'; valid: +x, -x, +y, -y, +z, -z")]
    UnknownUpAxis {
        /// The name asked for.
        name: String,
    },
    /// A view specification that cannot be parsed.
    #[error(
        "invalid view specification '{spec}': {reason} (expected grid:THETA,THETA,...:PHI_STEP or random:N)"
    )]
    InvalidViewSpec {
        /// The specification as given.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// A malformed line in a labels file.
    #[error("{}:{line}: {reason}", path.display())]
    Labels {
        /// The labels file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A camera calibration file (ROS camera_info or OpenCV FileStorage
    /// YAML) that cannot be read as a calibration.
    #[error("{}: {reason}", path.display())]
    Calibration {
        /// The calibration file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

impl CaptureError {
    /// Wraps an I/O error with the path it concerns.
    pub(crate) fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        CaptureError::Io {
            path: path.into(),
            cause,
        }
    }
}
