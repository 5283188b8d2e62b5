//! Wavefront OBJ loading, with `tobj` doing the parsing and triangulation.
//!
//! Object rule (issue #2): one object per `o` group; when the file has no
//! `o` line, one per `g` group; when it has neither, the whole file is one
//! object named after the file. Objects come in file order and keep the
//! names written in the file (a bare `o`/`g` gives tobj's
//! `unnamed_object`). Faces before the first group statement form an object
//! named after the file. A group without faces (or with faces of zero area
//! only) is an empty object, listed in its place (issue 15: "empty groups
//! are listed, not dropped"). Polygons are fan-triangulated by tobj; texture
//! coordinates, normals, materials, smoothing groups, lines (`l`) and points
//! (`p`) are ignored.
//!
//! tobj starts a new model at every `o` *and* `g` line and names it after the
//! last one, and it reports errors without line numbers. So the text is fed
//! through [`ObjLines`], a filtering reader that
//! - drops `g` lines when the file has `o` lines (so groups inside an object
//!   do not split it), and every line vis5d ignores,
//! - starts the file with a synthetic `o`/`g` line named after the file,
//! - checks every face's vertex indices and every vertex's coordinates as it
//!   passes, so errors carry the exact line number,
//! - notes every group and how many faces it hands tobj, and hands it each
//!   group line as `o NAME`: tobj makes no model of a group without faces
//!   (but the last), so the empty groups are put back in their places from
//!   this list.

use std::io::{self, BufRead};
use std::path::Path;

use glam::DVec3;

use super::{Scene, SceneBuilder, SceneError, SceneFormat};

/// Parses OBJ text `bytes` read from `path`.
pub(super) fn load_obj(
    path: &Path,
    bytes: &[u8],
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    let has_o = has_statement(bytes, b'o');
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "scene".to_owned());
    // As tobj names it (a stem of white space alone, or with some around
    // it, is read back trimmed).
    let stem = tobj_name(&stem);
    let keyword = if has_o { "o" } else { "g" };
    let mut reader = ObjLines {
        rest: bytes,
        total: bytes.len() as u64,
        line: Vec::with_capacity(256),
        pos: 0,
        line_no: 0,
        synthetic: Some(format!("{keyword} {stem}\n")),
        drop_g: has_o,
        vertices: 0,
        skipped: 0,
        group: stem.clone(),
        groups: Vec::new(),
        rewrite: None,
        error: None,
        progress,
        reported: 0,
    };
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let parsed = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    });
    if let Some(e) = reader.error.take() {
        return Err(e.into_scene_error(path));
    }
    let models = match parsed {
        Ok((models, _materials)) => models,
        Err(e) => {
            return Err(SceneError::Syntax {
                path: path.to_owned(),
                line: reader.line_no,
                message: format!("{e} (as parsed by tobj)"),
            });
        }
    };
    let mut builder = SceneBuilder::new(SceneFormat::Obj);
    for _ in 0..reader.skipped {
        builder.skip_non_triangle();
    }
    // tobj's models are the groups with faces, in order, and the last
    // group whatever it holds; the empty groups come from the list.
    let internal = |what: &str| SceneError::Syntax {
        path: path.to_owned(),
        line: 0,
        message: format!("internal error: tobj's models do not match the groups ({what})"),
    };
    let mut made = models.iter();
    let last = reader.groups.len().saturating_sub(1);
    for (k, group) in reader.groups.iter().enumerate() {
        let model = if group.faces > 0 || k == last {
            Some(made.next().ok_or_else(|| internal("too few models"))?)
        } else {
            None
        };
        let model = model.filter(|_| group.faces > 0);
        if model.is_none() {
            if !group.synthetic {
                builder.begin_object(group.name.clone());
            }
            continue;
        }
        let model = model.expect("checked above");
        if model.name != group.name {
            return Err(internal(&format!("{:?} for {:?}", model.name, group.name)));
        }
        builder.begin_object(model.name.clone());
        let p = &model.mesh.positions;
        // Positions are parsed as f64 (tobj's `use_f64`): a model in
        // georeferenced coordinates keeps its precision until the scene's
        // frame is chosen.
        let vertex = |i: u32| {
            let i = 3 * i as usize;
            DVec3::new(p[i], p[i + 1], p[i + 2])
        };
        for tri in model.mesh.indices.chunks_exact(3) {
            let t = [vertex(tri[0]), vertex(tri[1]), vertex(tri[2])];
            builder
                .push_triangle_f64(t)
                .map_err(|bad| SceneError::NonFinite {
                    path: path.to_owned(),
                    line: 0,
                    object: model.name.clone(),
                    value: bad.0.to_string(),
                })?;
        }
    }
    if made.next().is_some() {
        return Err(internal("too many models"));
    }
    // tobj's copy is no longer needed: free it before the builder makes
    // the scene's own.
    drop(models);
    builder.finish(path)
}

/// Whether some line of `bytes` starts with the statement `keyword` (a
/// single letter followed by white space or the end of the line).
fn has_statement(bytes: &[u8], keyword: u8) -> bool {
    bytes.split(|&b| b == b'\n').any(|line| {
        let line = line.trim_ascii_start();
        line.first() == Some(&keyword) && line.get(1).is_none_or(|b| b.is_ascii_whitespace())
    })
}

/// The name tobj gives a group whose `o` or `g` line ends in `rest`: `rest`
/// trimmed, `unnamed_object` when nothing is left.
fn tobj_name(rest: &str) -> String {
    match rest.trim() {
        "" => "unnamed_object".to_owned(),
        name => name.to_owned(),
    }
}

/// An error found by [`ObjLines`] on the way, with its line.
#[derive(Debug)]
struct LineError {
    line: usize,
    kind: LineErrorKind,
}

#[derive(Debug)]
enum LineErrorKind {
    Syntax(String),
    Index(String),
    NonFinite { object: String, value: String },
}

impl LineError {
    fn into_scene_error(self, path: &Path) -> SceneError {
        let (path, line) = (path.to_owned(), self.line);
        match self.kind {
            LineErrorKind::Syntax(message) => SceneError::Syntax {
                path,
                line,
                message,
            },
            LineErrorKind::Index(message) => SceneError::IndexOutOfRange {
                path,
                line,
                message,
            },
            LineErrorKind::NonFinite { object, value } => SceneError::NonFinite {
                path,
                line,
                object,
                value,
            },
        }
    }
}

/// A group statement met by [`ObjLines`].
#[derive(Debug)]
struct Group {
    /// Its name, as tobj names it.
    name: String,
    /// The synthetic group named after the file (an object only when
    /// faces come before the first group statement).
    synthetic: bool,
    /// The faces handed to tobj in it.
    faces: usize,
}

/// The filtering, checking reader described in the module docs. It hands
/// tobj one line at a time.
struct ObjLines<'a, 'p> {
    rest: &'a [u8],
    total: u64,
    line: Vec<u8>,
    pos: usize,
    /// 1-based number of the last line read from the file.
    line_no: usize,
    synthetic: Option<String>,
    drop_g: bool,
    /// Vertices (`v` lines) seen so far: the valid face index range.
    vertices: u64,
    /// `l`, `p` and short `f` statements skipped.
    skipped: usize,
    /// The current object's name, for messages.
    group: String,
    /// Every group met, the synthetic first one included, in order.
    groups: Vec<Group>,
    /// The line to hand tobj instead of the one read.
    rewrite: Option<String>,
    error: Option<LineError>,
    progress: &'p mut dyn FnMut(u64, u64),
    reported: u64,
}

impl ObjLines<'_, '_> {
    /// Reads the next line worth handing to tobj into `self.line`; false at
    /// the end of the text or after an error.
    fn next_line(&mut self) -> bool {
        if let Some(s) = self.synthetic.take() {
            self.groups.push(Group {
                name: self.group.clone(),
                synthetic: true,
                faces: 0,
            });
            self.line.clear();
            self.line.extend_from_slice(s.as_bytes());
            return true;
        }
        while !self.rest.is_empty() && self.error.is_none() {
            let end = self
                .rest
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.rest.len(), |i| i + 1);
            let (raw, rest) = self.rest.split_at(end);
            self.rest = rest;
            self.line_no += 1;
            let done = self.total - rest.len() as u64;
            if done - self.reported >= 1 << 20 || rest.is_empty() {
                self.reported = done;
                (self.progress)(done, self.total);
            }
            match self.check(raw) {
                Ok(true) => {
                    self.line.clear();
                    match self.rewrite.take() {
                        Some(line) => self.line.extend_from_slice(line.as_bytes()),
                        None => self.line.extend_from_slice(raw),
                    }
                    return true;
                }
                Ok(false) => {}
                Err(kind) => {
                    self.error = Some(LineError {
                        line: self.line_no,
                        kind,
                    });
                }
            }
        }
        false
    }

    /// Checks one raw line; Ok(true) if tobj should see it.
    fn check(&mut self, raw: &[u8]) -> Result<bool, LineErrorKind> {
        let text = std::str::from_utf8(raw)
            .map_err(|_| LineErrorKind::Syntax("the line is not valid UTF-8".into()))?;
        let mut words = text.split_whitespace();
        match words.next() {
            Some("v") => {
                self.vertices += 1;
                // Only lines with letters can spell nan/inf or overflow
                // through an exponent: parse just those.
                if text.bytes().any(|b| b.is_ascii_alphabetic() && b != b'v') {
                    for w in words.take(4) {
                        match w.parse::<f64>() {
                            Ok(x) if x.is_finite() => {}
                            Ok(_) => {
                                return Err(LineErrorKind::NonFinite {
                                    object: self.group.clone(),
                                    value: w.to_owned(),
                                });
                            }
                            Err(_) => {
                                return Err(LineErrorKind::Syntax(format!(
                                    "vertex coordinate {w:?} is not a number"
                                )));
                            }
                        }
                    }
                }
                Ok(true)
            }
            Some("f") => {
                let mut n = 0;
                for w in words {
                    self.check_index(w)?;
                    n += 1;
                }
                if n < 3 {
                    self.skipped += 1;
                    return Ok(false);
                }
                if let Some(g) = self.groups.last_mut() {
                    g.faces += 1;
                }
                Ok(true)
            }
            Some("o") => {
                self.start_group(text);
                Ok(true)
            }
            Some("g") => {
                if self.drop_g {
                    return Ok(false);
                }
                self.start_group(text);
                Ok(true)
            }
            Some("l") | Some("p") => {
                self.skipped += 1;
                Ok(false)
            }
            // Everything else (comments, vt, vn, usemtl, mtllib, s, ...) is
            // ignored; tobj does not need to see it.
            _ => Ok(false),
        }
    }

    /// Notes the group that the `o` or `g` line `text` starts, named as
    /// tobj names it (the rest of the line, trimmed; `unnamed_object` when
    /// there is none), and hands tobj the line as `o NAME` (tobj would take
    /// a line's leading white space into the name).
    fn start_group(&mut self, text: &str) {
        let name = tobj_name(&text.trim()[1..]);
        self.group.clone_from(&name);
        self.rewrite = Some(format!("o {name}\n"));
        self.groups.push(Group {
            name,
            synthetic: false,
            faces: 0,
        });
    }

    /// Checks one face vertex `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    fn check_index(&self, word: &str) -> Result<(), LineErrorKind> {
        let first = word.split('/').next().unwrap_or_default();
        let i: i64 = first.parse().map_err(|_| {
            LineErrorKind::Syntax(format!("face vertex {word:?} does not start with an index"))
        })?;
        let n = self.vertices as i64;
        let ok = (i > 0 && i <= n) || (i < 0 && -i <= n);
        if ok {
            Ok(())
        } else if i == 0 {
            Err(LineErrorKind::Index(
                "face vertex index 0: OBJ indices start at 1 (or count back from -1)".into(),
            ))
        } else {
            Err(LineErrorKind::Index(format!(
                "face vertex index {i} is out of range: {n} vertices are defined before this line"
            )))
        }
    }
}

impl io::Read for ObjLines<'_, '_> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let n = {
            let buf = self.fill_buf()?;
            let n = buf.len().min(out.len());
            out[..n].copy_from_slice(&buf[..n]);
            n
        };
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for ObjLines<'_, '_> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.pos >= self.line.len() {
            self.pos = 0;
            if !self.next_line() {
                self.line.clear();
                if self.error.is_some() {
                    return Err(io::Error::other("stopped at an invalid line"));
                }
            }
        }
        Ok(&self.line[self.pos..])
    }

    fn consume(&mut self, amount: usize) {
        self.pos += amount;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> Result<Scene, SceneError> {
        load_obj(Path::new("dir/model.obj"), text.as_bytes(), &mut |_, _| {})
    }

    fn names(s: &Scene) -> Vec<(&str, usize)> {
        s.objects()
            .iter()
            .map(|o| (o.name.as_str(), o.triangle_count()))
            .collect()
    }

    const VERTS: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn o_groups_are_objects_and_g_inside_o_does_not_split() {
        let text =
            format!("{VERTS}o first\ng part1\nf 1 2 3\ng part2\nf 1 3 4\no second\nf 1 2 3 4\n");
        let s = load(&text).unwrap();
        assert_eq!(names(&s), [("first", 2), ("second", 2)]);
        s.validate().unwrap();
    }

    #[test]
    fn g_groups_are_objects_when_there_is_no_o() {
        let text = format!("{VERTS}g a\nf 1 2 3\ng b\nf 1 3 4\ng a\nf 1 2 4\n");
        let s = load(&text).unwrap();
        assert_eq!(names(&s), [("a", 1), ("b", 1), ("a", 1)]);
        assert_eq!(s.report().duplicate_names, [("a".to_owned(), 2)]);
    }

    #[test]
    fn no_groups_means_one_object_named_after_the_file() {
        let s = load(&format!("{VERTS}f 1 2 3\nf -4 -2 -1\n")).unwrap();
        assert_eq!(names(&s), [("model", 2)]);
        // A stem with white space around it is named as tobj reads it.
        for (file, name) in [(" my model .obj", "my model"), (" .obj", "unnamed_object")] {
            let text = format!("{VERTS}f 1 2 3\no x\n");
            let s = load_obj(Path::new(file), text.as_bytes(), &mut |_, _| {}).unwrap();
            assert_eq!(names(&s), [(name, 1), ("x", 0)], "{file:?}");
        }
    }

    #[test]
    fn faces_before_the_first_group_belong_to_the_file() {
        let s = load(&format!("{VERTS}f 1 2 3\no x\nf 1 3 4\n")).unwrap();
        assert_eq!(names(&s), [("model", 1), ("x", 1)]);
    }

    #[test]
    fn polygons_are_triangulated_and_extras_ignored() {
        let text = format!(
            "mtllib m.mtl\n{VERTS}v 0.5 2 0\nvt 0 0\nvn 0 0 1\nusemtl red\ns 1\n\
             o penta\nf 1/1/1 2/1/1 3//1 5 4\nl 1 2\np 3\nf 1 2\n"
        );
        let s = load(&text).unwrap();
        assert_eq!(names(&s), [("penta", 3)]);
        assert_eq!(s.report().skipped_non_triangles, 3);
    }

    #[test]
    fn degenerate_triangles_are_dropped_and_empty_groups_listed() {
        let text = format!("{VERTS}o empty\no flat\nf 1 2 2\no ok\nf 1 2 3\no\n  o  last one \n");
        let s = load(&text).unwrap();
        s.validate().unwrap();
        assert_eq!(
            names(&s),
            [
                ("empty", 0),
                ("flat", 0),
                ("ok", 1),
                ("unnamed_object", 0),
                ("last one", 0)
            ]
        );
        assert_eq!(s.report().dropped_degenerate, 1);
        assert_eq!(s.report().empty_objects, [0, 1, 3, 4]);
        // Without `o`, the `g` groups; faces before them make the file's
        // object, which is not listed when there are none.
        let s = load(&format!("{VERTS}g a\ng b\nf 1 2 3\ng c\n")).unwrap();
        assert_eq!(names(&s), [("a", 0), ("b", 1), ("c", 0)]);
        let s = load(&format!("{VERTS}f 1 2 3\ng a\n")).unwrap();
        assert_eq!(names(&s), [("model", 1), ("a", 0)]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let cases = [
            (
                format!("{VERTS}o a\nf 1 2 9\n"),
                "dir/model.obj:6: face vertex index 9",
            ),
            (
                format!("{VERTS}f 0 1 2\n"),
                "dir/model.obj:5: face vertex index 0",
            ),
            (
                format!("{VERTS}f -5 1 2\n"),
                "dir/model.obj:5: face vertex index -5",
            ),
            (
                format!("{VERTS}f a b c\n"),
                "dir/model.obj:5: face vertex \"a\"",
            ),
            (
                "o a\nv 0 nan 0\n".into(),
                "dir/model.obj:2: object \"a\" has a vertex",
            ),
            (
                // Beyond f64 (1e39 is a coordinate: positions are f64).
                "v 0 1e309 0\n".into(),
                "dir/model.obj:1: object \"model\" has a vertex",
            ),
            (
                "v 0 0 zero\n".into(),
                "dir/model.obj:1: vertex coordinate \"zero\"",
            ),
            ("v 0 0\n".into(), "dir/model.obj:1: position parse error"),
            (
                format!("{VERTS}f 1 2 2\n"),
                "dir/model.obj: the scene has no triangles",
            ),
            (
                "# nothing\n".into(),
                "dir/model.obj: the scene has no triangles",
            ),
        ];
        for (text, want) in cases {
            let e = load(&text).unwrap_err().to_string();
            assert!(e.starts_with(want), "{text:?}\n gave {e:?}\n want {want:?}");
        }
    }

    #[test]
    fn invalid_utf8_is_an_error_not_a_panic() {
        let e = load_obj(Path::new("x.obj"), b"v 0 0 0\n\xff\xfe\n", &mut |_, _| {})
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.obj:2: the line is not valid UTF-8"), "{e}");
    }

    #[test]
    fn crlf_and_missing_final_newline() {
        let s = load("o a\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3").unwrap();
        assert_eq!(names(&s), [("a", 1)]);
    }
}
