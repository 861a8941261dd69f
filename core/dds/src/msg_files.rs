//! The Rust message types checked against the `.msg` files of `ros2/skein_msgs/msg/`,
//! where skein's messages are defined once, and against those of the standard packages
//! the repository carries for the ROS 2 peers (`tests/peers/ros2/<package>/msg/`:
//! `tf2_msgs`, `rtcm_msgs`): every such sample of [`crate::msg_samples`] is walked by a
//! recording serde serializer (field names, CDR primitive types, arrays and sequences,
//! nested messages in order) and compared with its `.msg` file, read at test time. A
//! field added, removed, renamed, retyped or moved on one side only fails here, without
//! ROS installed; `tests/e2e_ros2.rs` compares the bytes with the rosidl-generated types.

use crate::msg_samples::{SampleVisitor, visit_all};
use crate::msgs::RosMessage;
use serde::ser::{self, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// What a serialized value is, as a `.msg` file would name it.
#[derive(Debug, Clone, PartialEq)]
enum Shape {
    /// A `.msg` primitive (`float64`, `uint8`, `string`, `bool` …).
    Prim(&'static str),
    /// A message: its fields in order.
    Msg(Vec<(String, Shape)>),
    /// `T[N]`.
    Array(usize, Box<Shape>),
    /// `T[]` (the shape of the sample's first element).
    Seq(Box<Shape>),
}

#[derive(Debug)]
struct ShapeError(String);

impl std::fmt::Display for ShapeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ShapeError {}

impl ser::Error for ShapeError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        ShapeError(msg.to_string())
    }
}

/// The recording serializer.
struct Recorder;

/// A struct, tuple (fixed array) or sequence being recorded.
struct Compound {
    fields: Vec<(String, Shape)>,
    kind: Kind,
}

enum Kind {
    Struct,
    Array,
    Seq,
}

type R = Result<Shape, ShapeError>;

impl Compound {
    fn element<T: ?Sized + Serialize>(&mut self, key: &str, v: &T) -> Result<(), ShapeError> {
        self.fields.push((key.to_string(), v.serialize(Recorder)?));
        Ok(())
    }

    fn finish(self) -> R {
        match self.kind {
            Kind::Struct => Ok(Shape::Msg(self.fields)),
            Kind::Array | Kind::Seq => {
                let n = self.fields.len();
                let first = self.fields.into_iter().next().map(|(_, s)| s);
                let elem = first.ok_or_else(|| ShapeError("an empty array or sequence".into()))?;
                Ok(match self.kind {
                    Kind::Array => Shape::Array(n, Box::new(elem)),
                    _ => Shape::Seq(Box::new(elem)),
                })
            }
        }
    }
}

macro_rules! prim {
    ($($f:ident: $t:ty => $name:literal),* $(,)?) => {
        $(fn $f(self, _: $t) -> R { Ok(Shape::Prim($name)) })*
    };
}

macro_rules! unsupported {
    ($($f:ident($($a:ty),*)),* $(,)?) => {
        $(fn $f(self, $(_: $a),*) -> R {
            Err(ShapeError(concat!(stringify!($f), " has no .msg form").into()))
        })*
    };
}

impl ser::Serializer for Recorder {
    type Ok = Shape;
    type Error = ShapeError;
    type SerializeSeq = Compound;
    type SerializeTuple = Compound;
    type SerializeTupleStruct = Compound;
    type SerializeTupleVariant = ser::Impossible<Shape, ShapeError>;
    type SerializeMap = ser::Impossible<Shape, ShapeError>;
    type SerializeStruct = Compound;
    type SerializeStructVariant = ser::Impossible<Shape, ShapeError>;

    prim! {
        serialize_bool: bool => "bool",
        serialize_i8: i8 => "int8",
        serialize_i16: i16 => "int16",
        serialize_i32: i32 => "int32",
        serialize_i64: i64 => "int64",
        serialize_u8: u8 => "uint8",
        serialize_u16: u16 => "uint16",
        serialize_u32: u32 => "uint32",
        serialize_u64: u64 => "uint64",
        serialize_f32: f32 => "float32",
        serialize_f64: f64 => "float64",
        serialize_str: &str => "string",
    }

    unsupported! {
        serialize_char(char),
        serialize_bytes(&[u8]),
        serialize_none(),
        serialize_unit(),
        serialize_unit_struct(&'static str),
        serialize_unit_variant(&'static str, u32, &'static str),
    }

    fn serialize_some<T: ?Sized + Serialize>(self, _: &T) -> R {
        Err(ShapeError("an Option has no .msg form".into()))
    }

    fn serialize_newtype_struct<T: ?Sized + Serialize>(self, _: &'static str, v: &T) -> R {
        v.serialize(self)
    }

    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> R {
        Err(ShapeError("an enum has no .msg form".into()))
    }

    fn serialize_seq(self, _: Option<usize>) -> Result<Compound, ShapeError> {
        Ok(Compound {
            fields: vec![],
            kind: Kind::Seq,
        })
    }

    fn serialize_tuple(self, _: usize) -> Result<Compound, ShapeError> {
        Ok(Compound {
            fields: vec![],
            kind: Kind::Array,
        })
    }

    fn serialize_tuple_struct(self, _: &'static str, n: usize) -> Result<Compound, ShapeError> {
        self.serialize_tuple(n)
    }

    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, ShapeError> {
        Err(ShapeError("an enum has no .msg form".into()))
    }

    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, ShapeError> {
        Err(ShapeError("a map has no .msg form".into()))
    }

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Compound, ShapeError> {
        Ok(Compound {
            fields: vec![],
            kind: Kind::Struct,
        })
    }

    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, ShapeError> {
        Err(ShapeError("an enum has no .msg form".into()))
    }
}

impl ser::SerializeSeq for Compound {
    type Ok = Shape;
    type Error = ShapeError;
    fn serialize_element<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), ShapeError> {
        self.element("", v)
    }
    fn end(self) -> R {
        self.finish()
    }
}

impl ser::SerializeTuple for Compound {
    type Ok = Shape;
    type Error = ShapeError;
    fn serialize_element<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), ShapeError> {
        self.element("", v)
    }
    fn end(self) -> R {
        self.finish()
    }
}

impl ser::SerializeTupleStruct for Compound {
    type Ok = Shape;
    type Error = ShapeError;
    fn serialize_field<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), ShapeError> {
        self.element("", v)
    }
    fn end(self) -> R {
        self.finish()
    }
}

impl ser::SerializeStruct for Compound {
    type Ok = Shape;
    type Error = ShapeError;
    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        v: &T,
    ) -> Result<(), ShapeError> {
        self.element(key, v)
    }
    fn end(self) -> R {
        self.finish()
    }
}

/// The definitions of the standard messages the checked ones use (ROS 2 Jazzy's
/// `common_interfaces` and `rcl_interfaces`): no ROS installation is needed here.
const STANDARD: [(&str, &str); 7] = [
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec"),
    (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\nstring frame_id",
    ),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z"),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z"),
    (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    ),
    (
        "geometry_msgs/Transform",
        "Vector3 translation\nQuaternion rotation",
    ),
    (
        "geometry_msgs/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\nTransform transform",
    ),
];

/// The repository's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The standard packages carried for the ROS 2 peers, by name: `tests/peers/ros2/<name>/`.
fn carried_packages() -> Vec<String> {
    let dir = root().join("tests/peers/ros2");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("tests/peers/ros2")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("msg").is_dir())
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    names.sort();
    names
}

/// Adds the `.msg` files of `dir` to `defs` as `package/Type`.
fn read_msg_dir(defs: &mut BTreeMap<String, String>, package: &str, dir: &std::path::Path) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.expect("a directory entry").path();
        if path.extension().is_some_and(|e| e == "msg") {
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            let text = std::fs::read_to_string(&path).expect("a .msg file");
            defs.insert(format!("{package}/{name}"), text);
        }
    }
}

/// Every definition by `package/Type`: the `.msg` files of `ros2/skein_msgs`, those of
/// the carried packages, and [`STANDARD`].
fn definitions() -> BTreeMap<String, String> {
    let mut defs: BTreeMap<String, String> = STANDARD
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    read_msg_dir(&mut defs, "skein_msgs", &root().join("ros2/skein_msgs/msg"));
    for package in carried_packages() {
        let dir = root().join("tests/peers/ros2").join(&package).join("msg");
        read_msg_dir(&mut defs, &package, &dir);
    }
    defs
}

/// The fields of a `.msg` text: `(type, name)` in order, comments and constants
/// (`TYPE NAME=value`) left out.
fn fields(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            let (ty, name) = (it.next()?, it.next()?);
            (!name.contains('=')).then(|| (ty.to_string(), name.to_string()))
        })
        .collect()
}

/// Compares `shape` with `.msg` type `ty` of package `pkg`; the differences, each named
/// by its field path.
fn compare(
    defs: &BTreeMap<String, String>,
    pkg: &str,
    ty: &str,
    shape: &Shape,
    path: &str,
) -> Vec<String> {
    // T[] and T[N]; bounds (`T[<=N]`, `string<=N`) are not used by skein.
    if let Some(elem) = ty.strip_suffix("[]") {
        return match shape {
            Shape::Seq(s) => compare(defs, pkg, elem, s, &format!("{path}[]")),
            other => vec![format!("{path}: `{ty}` is a sequence, Rust has {other:?}")],
        };
    }
    if let Some((elem, n)) = ty.strip_suffix(']').and_then(|t| t.split_once('[')) {
        let n: usize = n.parse().expect("an array length");
        return match shape {
            Shape::Array(m, s) if *m == n => compare(defs, pkg, elem, s, &format!("{path}[]")),
            other => vec![format!("{path}: `{ty}`, Rust has {other:?}")],
        };
    }
    let primitive = [
        "bool", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
        "float32", "float64", "string",
    ];
    if primitive.contains(&ty) {
        return match shape {
            Shape::Prim(p) if *p == ty => vec![],
            other => vec![format!("{path}: `{ty}`, Rust has {other:?}")],
        };
    }
    let full = if ty.contains('/') {
        ty.to_string()
    } else {
        format!("{pkg}/{ty}")
    };
    let Some(text) = defs.get(&full) else {
        return vec![format!("{path}: no definition of `{full}` here")];
    };
    let Shape::Msg(rust) = shape else {
        return vec![format!("{path}: `{full}` is a message, Rust has {shape:?}")];
    };
    let msg = fields(text);
    let mut diffs = vec![];
    if msg.len() != rust.len() {
        diffs.push(format!(
            "{path}: `{full}` has {} fields ({:?}), Rust {} ({:?})",
            msg.len(),
            msg.iter().map(|(_, n)| n).collect::<Vec<_>>(),
            rust.len(),
            rust.iter().map(|(n, _)| n).collect::<Vec<_>>()
        ));
    }
    let field_pkg = full.split('/').next().unwrap_or(pkg);
    for ((ty, name), (rust_name, s)) in msg.iter().zip(rust) {
        let at = format!("{path}.{name}");
        if name != rust_name {
            diffs.push(format!("{at}: Rust has `{rust_name}` in its place"));
        }
        diffs.extend(compare(defs, field_pkg, ty, s, &at));
    }
    diffs
}

/// Collects the shape of each sample of package `.0`.
struct Shapes(String, Vec<(String, Result<Shape, String>)>);

impl SampleVisitor for Shapes {
    fn sample<M: RosMessage>(&mut self, m: &M) {
        let (pkg, ty) = M::TYPE;
        if pkg == self.0 {
            let shape = m.serialize(Recorder).map_err(|e| e.to_string());
            self.1.push((ty.to_string(), shape));
        }
    }
}

impl Shapes {
    fn of(package: &str) -> Self {
        let mut shapes = Shapes(package.to_string(), vec![]);
        visit_all(&mut shapes);
        shapes
    }
}

#[test]
fn every_skein_msgs_type_matches_its_msg_file() {
    let defs = definitions();
    let shapes = Shapes::of("skein_msgs");
    let files: Vec<&str> = defs
        .keys()
        .filter_map(|k| k.strip_prefix("skein_msgs/"))
        .collect();
    let checked: Vec<&str> = shapes.1.iter().map(|(t, _)| t.as_str()).collect();
    let mut sorted = checked.clone();
    sorted.sort();
    assert_eq!(
        sorted, files,
        "a sample for every .msg file, and a file for every sample"
    );
    for (ty, shape) in &shapes.1 {
        let shape = shape.as_ref().unwrap_or_else(|e| panic!("{ty}: {e}"));
        let diffs = compare(&defs, "skein_msgs", ty, shape, ty);
        assert!(diffs.is_empty(), "{}", diffs.join("\n"));
    }
}

#[test]
fn every_type_of_a_carried_package_matches_its_msg_file() {
    let defs = definitions();
    let packages = carried_packages();
    assert_eq!(packages, ["rtcm_msgs", "tf2_msgs"]);
    for package in &packages {
        let shapes = Shapes::of(package);
        let prefix = format!("{package}/");
        let files: Vec<&str> = defs
            .keys()
            .filter_map(|k| k.strip_prefix(&prefix))
            .collect();
        let mut checked: Vec<&str> = shapes.1.iter().map(|(t, _)| t.as_str()).collect();
        checked.sort();
        assert_eq!(checked, files, "{package}: a sample for every .msg file");
        for (ty, shape) in &shapes.1 {
            let shape = shape.as_ref().unwrap_or_else(|e| panic!("{ty}: {e}"));
            let diffs = compare(&defs, package, ty, shape, &format!("{package}/{ty}"));
            assert!(diffs.is_empty(), "{}", diffs.join("\n"));
        }
    }
}

#[test]
fn a_drifted_field_is_named() {
    let defs = definitions();
    let shapes = Shapes::of("skein_msgs");
    let (_, shape) = shapes.1.iter().find(|(t, _)| t == "Command").unwrap();
    let Ok(Shape::Msg(mut f)) = shape.clone() else {
        panic!("Command is a message")
    };
    f[1].1 = Shape::Prim("uint32"); // request_id: uint64 in the file
    f.swap(4, 3); // force and altitude_m swapped
    let diffs = compare(&defs, "skein_msgs", "Command", &Shape::Msg(f), "Command");
    assert!(
        diffs
            .iter()
            .any(|d| d.contains("Command.request_id: `uint64`")),
        "{diffs:?}"
    );
    assert!(
        diffs
            .iter()
            .any(|d| d.contains("Command.altitude_m: Rust has `force`")),
        "{diffs:?}"
    );
}
