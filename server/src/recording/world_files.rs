//! The files a world is made of, read into memory so a recording carries them: the world file first, then
//! every file it names under a `mesh` key (objects' meshes, mesh tools), by the relative path it names them.

use std::path::{Component, Path, PathBuf};

/// One file of a world.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WorldFile {
    /// Its name in the recording: the world file's own file name, or a mesh path as the world names it.
    pub name: String,
    /// MIME type.
    pub media_type: &'static str,
    /// Contents.
    pub data: Vec<u8>,
}

/// The world file at `source` and the mesh files it names. Err: the file that could not be read, and why.
pub fn world_files(source: &Path) -> Result<Vec<WorldFile>, (PathBuf, String)> {
    let text = std::fs::read_to_string(source).map_err(|e| (source.to_owned(), e.to_string()))?;
    let name = source
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "world.toml".to_owned());
    let mut files = vec![WorldFile {
        name,
        media_type: "application/toml",
        data: text.clone().into_bytes(),
    }];
    let value = toml::Value::Table(
        toml::from_str::<toml::Table>(&text).map_err(|e| (source.to_owned(), e.to_string()))?,
    );
    let mut meshes = Vec::new();
    collect_mesh_paths(&value, &mut meshes);
    meshes.sort();
    meshes.dedup();
    let dir = source.parent().unwrap_or(Path::new("."));
    for mesh in meshes {
        if !is_plain_relative(Path::new(&mesh)) {
            return Err((
                PathBuf::from(&mesh),
                "a recorded world may name its meshes only by paths inside its own folder (no absolute \
                 path, no `..`)"
                    .to_owned(),
            ));
        }
        let path = dir.join(&mesh);
        let data = std::fs::read(&path).map_err(|e| (path.clone(), e.to_string()))?;
        files.push(WorldFile {
            name: mesh,
            media_type: "application/octet-stream",
            data,
        });
    }
    Ok(files)
}

/// A relative path with only normal components (it cannot leave the folder it is joined to).
pub fn is_plain_relative(path: &Path) -> bool {
    path.components().count() > 0 && path.components().all(|c| matches!(c, Component::Normal(_)))
}

fn collect_mesh_paths(value: &toml::Value, out: &mut Vec<String>) {
    match value {
        toml::Value::Table(table) => {
            for (key, value) in table {
                match (key.as_str(), value) {
                    ("mesh", toml::Value::String(path)) => out.push(path.clone()),
                    _ => collect_mesh_paths(value, out),
                }
            }
        }
        toml::Value::Array(items) => {
            for item in items {
                collect_mesh_paths(item, out);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pad_carries_its_world_file_and_its_mesh() {
        let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
        let files = world_files(&source).unwrap();
        let names: Vec<&str> = files.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["pad.toml", "meshes/pad.obj"]);
        assert!(files[1].data.len() > 1000);
    }

    #[test]
    fn paths_that_leave_the_folder_are_not_plain() {
        assert!(is_plain_relative(Path::new("meshes/pad.obj")));
        assert!(!is_plain_relative(Path::new("../pad.obj")));
        assert!(!is_plain_relative(Path::new("/etc/passwd")));
        assert!(!is_plain_relative(Path::new("")));
    }
}
