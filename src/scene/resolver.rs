//! Mitsuba's file resolver: where a relative file name in a scene is looked for.
//!
//! Mitsuba keeps one ordered list of directories and resolves a relative name to the first
//! `directory/name` that exists, or to the name itself (relative to the working directory)
//! when none does. While a scene file is parsed the list is, front to back: the folders added
//! by `<path value="..."/>` (the latest first), the scene file's directory, the working
//! directory. An `<include>` puts the including file's directory in front while the included
//! file is parsed, and whatever that file adds is dropped afterwards. Plugins (meshes, images)
//! resolve their `filename` after parsing, against the list the main file leaves behind; so a
//! mesh named in an included file is looked for in the main scene's folders, not next to the
//! included file, exactly as in Mitsuba 3.9.1 (`src/core/fresolver.cpp`, `src/core/parser.cpp`).

use std::path::{Path, PathBuf};

/// An ordered list of directories searched for relative file names.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FileResolver {
    paths: Vec<PathBuf>,
    /// The scene file's directory, where a name found nowhere is reported missing.
    scene_dir: PathBuf,
}

impl FileResolver {
    /// The resolver of a scene file in `scene_dir`: that directory, then the working directory.
    pub fn for_scene(scene_dir: &Path) -> Self {
        let mut paths = vec![scene_dir.to_path_buf()];
        if let Ok(cwd) = std::env::current_dir() {
            paths.push(cwd);
        }
        FileResolver {
            paths,
            scene_dir: scene_dir.to_path_buf(),
        }
    }

    /// Searches `dir` before everything else.
    pub fn prepend(&mut self, dir: PathBuf) {
        self.paths.insert(0, dir);
    }

    /// The directories, in search order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Like [`FileResolver::resolve`], but a relative name found nowhere is placed in the
    /// scene's directory, so that the error of opening it names a useful path.
    pub fn resolve_file(&self, name: &Path) -> PathBuf {
        let found = self.resolve(name);
        if found.is_relative() && !found.exists() {
            self.scene_dir.join(name)
        } else {
            found
        }
    }

    /// The first `dir/name` that exists, or `name` itself (absolute names are returned as
    /// they are), as Mitsuba's `FileResolver::resolve`.
    pub fn resolve(&self, name: &Path) -> PathBuf {
        if name.is_absolute() {
            return name.to_path_buf();
        }
        self.paths
            .iter()
            .map(|dir| dir.join(name))
            .find(|p| p.exists())
            .unwrap_or_else(|| name.to_path_buf())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn searches_in_order_and_falls_back_to_the_name() {
        let base = std::env::temp_dir().join(format!("penumbra-resolver-{}", std::process::id()));
        let (a, b) = (base.join("a"), base.join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(a.join("both.txt"), "a").unwrap();
        std::fs::write(b.join("both.txt"), "b").unwrap();
        std::fs::write(b.join("only_b.txt"), "b").unwrap();
        let mut r = FileResolver::default();
        r.prepend(b.clone());
        r.prepend(a.clone());
        assert_eq!(r.resolve(Path::new("both.txt")), a.join("both.txt"));
        assert_eq!(r.resolve(Path::new("only_b.txt")), b.join("only_b.txt"));
        assert_eq!(r.resolve(Path::new("none.txt")), PathBuf::from("none.txt"));
        let abs = base.join("x/abs.txt");
        assert_eq!(r.resolve(&abs), abs);
        std::fs::remove_dir_all(&base).unwrap();
    }
}
