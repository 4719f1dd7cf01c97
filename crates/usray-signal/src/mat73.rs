//! MATLAB v7.3 `.mat` reader: the file is HDF5 behind a 512-byte MATLAB user
//! block, read into the same [`MatFile`] as the v5 reader gives, so everything
//! built on [`crate::mat::read_mat`] (the Verasonics and full-matrix imports)
//! reads v7.3 files unchanged.
//!
//! Layout (MathWorks, "MAT-File Versions": "Version 7.3 MAT-files use an
//! HDF5-based format"; the object layout as MATLAB writes it and as h5py-based
//! tools such as `hdf5storage` and `mat73` read it):
//! - the 128-byte text header says `MATLAB 7.3 MAT-file`; the HDF5 superblock
//!   follows at offset 512;
//! - every top-level dataset or group whose name does not start with `#` is a
//!   variable (`#refs#` holds the targets of cell references, `#subsystem#`
//!   MATLAB's object data);
//! - the `MATLAB_class` attribute names the class: `double`, `single`,
//!   `int8`…`uint64`, `logical`, `char`, `struct`, `cell`, or a class name
//!   (objects, decoded by MATLAB itself: read as [`MatValue::Unsupported`]);
//! - arrays are stored with reversed dimensions: MATLAB `(a, b, c)` column-major is
//!   HDF5 shape `[c, b, a]` row-major, the same memory order, so values copy
//!   directly and the dimensions reverse;
//! - `char` arrays are `uint16` UTF-16 code units; complex arrays a compound type
//!   with members `real` and `imag`; empty arrays (attribute `MATLAB_empty` = 1)
//!   store their dimensions as their data; sparse arrays (attribute
//!   `MATLAB_sparse`) are groups, read as unsupported;
//! - a 1×1 struct is a group whose members are its fields, in the order of the
//!   `MATLAB_fields` attribute; a struct array is a group whose fields are
//!   datasets of object references, one per element; a cell array is a dataset of
//!   object references into `#refs#`.
//!
//! The limits of [`crate::mat::limits`] apply: the file size (checked by
//! `read_mat`), the values held (every number, character and reference counts,
//! taken before the read allocates) and the nesting of cells and structs (which
//! also stops reference cycles).

use std::io::Read;
use std::path::Path;

use hdf5::types::{FixedAscii, TypeDescriptor, VarLenArray};
use hdf5::{Dataset, Group, LocationType, ObjectReference1, ReferencedObject};

use crate::error::{Result, SignalError};
use crate::h5::{element_count, numeric_attr, read_f64, string_attr, R};
use crate::mat::{limits, Budget, MatFile, MatValue, NumericClass};

/// The text a v7.3 header starts with.
const HEADER_TEXT: &[u8] = b"MATLAB 7.3";
/// The HDF5 format signature (HDF5 File Format Specification, "Superblock").
const HDF5_SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";

/// MAT v5 class numbers [`MatValue::Unsupported`] carries for what v7.3 files
/// store but this reader does not decode (MAT-File Format, table 1-3).
mod unsupported {
    /// `mxSPARSE_CLASS`.
    pub const SPARSE: u8 = 5;
    /// `mxFUNCTION_CLASS`.
    pub const FUNCTION: u8 = 16;
    /// `mxOPAQUE_CLASS`: MATLAB objects (`classdef` instances, `string`, …).
    pub const OBJECT: u8 = 17;
}

/// Whether `path` is a MAT v7.3 file: its header says `MATLAB 7.3`, or it is a
/// bare HDF5 file (no MATLAB header).
pub(crate) fn is_mat73(path: &Path) -> Result<bool> {
    let mut head = Vec::with_capacity(128);
    std::fs::File::open(path)
        .and_then(|f| f.take(128).read_to_end(&mut head))
        .map_err(|e| SignalError::io(path, e))?;
    Ok(head.starts_with(HDF5_SIGNATURE) || head.starts_with(HEADER_TEXT))
}

/// Read every variable of the MAT v7.3 file `path`, in the file's (alphabetical)
/// order. The caller has checked the file size.
pub(crate) fn read_mat73(path: &Path) -> Result<MatFile> {
    let err = |w: String| SignalError::format(path, w);
    let file = hdf5::File::open(path)
        .map_err(|e| err(format!("MAT v7.3 file, but not readable as HDF5: {e}")))?;
    let mut reader = Reader {
        file: &file,
        budget: Budget {
            values_left: limits::MAX_VALUES,
        },
    };
    let names = file
        .member_names()
        .map_err(|e| err(format!("cannot list the variables: {e}")))?;
    let mut out = Vec::new();
    for name in names.into_iter().filter(|n| !n.starts_with('#')) {
        let node = Node::open(&file, &name).map_err(err)?;
        let value = reader.value(&node, &name, 0).map_err(err)?;
        out.push((name, value));
    }
    Ok(out)
}

/// A complex element as MATLAB stores it.
#[derive(hdf5::H5Type, Clone, Copy)]
#[repr(C)]
struct MatComplex {
    real: f64,
    imag: f64,
}

/// An object of the file: MATLAB values are groups (structs, sparse arrays) or
/// datasets (everything else).
enum Node {
    Group(Group),
    Dataset(Dataset),
}

impl Node {
    /// The member `name` of `group`.
    fn open(group: &Group, name: &str) -> R<Node> {
        let what = |e: hdf5::Error| format!("`{name}`: {e}");
        Ok(match group.loc_type_by_name(name).map_err(what)? {
            LocationType::Group => Node::Group(group.group(name).map_err(what)?),
            LocationType::Dataset => Node::Dataset(group.dataset(name).map_err(what)?),
            other => return Err(format!("`{name}` is a {other:?}, not a MATLAB value")),
        })
    }
    fn location(&self) -> &hdf5::Location {
        match self {
            Node::Group(g) => g,
            Node::Dataset(d) => d,
        }
    }
}

/// MATLAB dimensions of an HDF5 shape: reversed, at least two.
fn matlab_dims(shape: &[usize]) -> Vec<usize> {
    let mut dims: Vec<usize> = shape.iter().rev().copied().collect();
    dims.resize(dims.len().max(2), 1);
    dims
}

struct Reader<'f> {
    file: &'f hdf5::File,
    budget: Budget,
}

impl Reader<'_> {
    /// The value stored at `node`, `depth` levels inside cells and structs;
    /// `name` names it in errors (`param.fs`, `data{3}`).
    fn value(&mut self, node: &Node, name: &str, depth: usize) -> R<MatValue> {
        if depth > limits::MAX_NESTING {
            return Err(format!(
                "`{name}`: cells or structs nested deeper than {} levels (usray_signal::mat::limits::MAX_NESTING)",
                limits::MAX_NESTING
            ));
        }
        let loc = node.location();
        if loc.attr("MATLAB_sparse").is_ok() {
            return Ok(MatValue::Unsupported(unsupported::SPARSE));
        }
        let class = string_attr(loc, "MATLAB_class");
        let empty = numeric_attr(loc, "MATLAB_empty").is_some_and(|v| v.iter().any(|&x| x != 0.0));
        match (node, class.as_deref()) {
            (Node::Group(g), Some("struct") | None) => self.structure(g, name, depth),
            (_, Some("function_handle")) => Ok(MatValue::Unsupported(unsupported::FUNCTION)),
            (Node::Group(_), Some(_)) => Ok(MatValue::Unsupported(unsupported::OBJECT)),
            (Node::Dataset(d), _) if empty => self.empty(d, class.as_deref(), name),
            (Node::Dataset(d), Some("cell")) => self.cell(d, name, depth),
            (Node::Dataset(d), Some("char")) => self.chars(d, name),
            (Node::Dataset(d), None) => self.numeric(d, NumericClass::Double, name),
            (Node::Dataset(d), Some(c)) => match NumericClass::from_name(c) {
                Some(class) => self.numeric(d, class, name),
                None => Ok(MatValue::Unsupported(unsupported::OBJECT)),
            },
        }
    }

    /// An empty array: its data are its MATLAB dimensions.
    fn empty(&mut self, d: &Dataset, class: Option<&str>, name: &str) -> R<MatValue> {
        let n = element_count(&d.shape(), &format!("`{name}`"))?;
        self.budget.take(n, name)?;
        let dims: Vec<usize> = read_f64(d, name)?
            .into_iter()
            .map(|v| v.max(0.0) as usize)
            .collect();
        let dims = if dims.len() >= 2 { dims } else { vec![0, 0] };
        Ok(match class {
            Some("char") => MatValue::Char(String::new()),
            Some("cell") => MatValue::Cell {
                dims,
                cells: vec![],
            },
            Some("struct") => MatValue::Struct {
                dims,
                fields: vec![],
                elems: vec![],
            },
            other => MatValue::Numeric {
                class: other
                    .and_then(NumericClass::from_name)
                    .unwrap_or(NumericClass::Double),
                dims,
                re: vec![],
                im: None,
            },
        })
    }

    fn numeric(&mut self, d: &Dataset, class: NumericClass, name: &str) -> R<MatValue> {
        let shape = d.shape();
        let n = element_count(&shape, &format!("`{name}`"))?;
        let complex = matches!(
            d.dtype().and_then(|t| t.to_descriptor()),
            Ok(TypeDescriptor::Compound(_))
        );
        self.budget.take(if complex { 2 * n } else { n }, name)?;
        let (re, im) = if complex {
            let z = d
                .read_raw::<MatComplex>()
                .map_err(|e| format!("complex array `{name}` lacks `real`/`imag` members: {e}"))?;
            (
                z.iter().map(|z| z.real).collect(),
                Some(z.iter().map(|z| z.imag).collect()),
            )
        } else {
            (read_f64(d, &format!("array `{name}`"))?, None)
        };
        Ok(MatValue::Numeric {
            class,
            dims: matlab_dims(&shape),
            re,
            im,
        })
    }

    fn chars(&mut self, d: &Dataset, name: &str) -> R<MatValue> {
        let n = element_count(&d.shape(), &format!("`{name}`"))?;
        self.budget.take(n, name)?;
        let units = d
            .read_raw::<u16>()
            .map_err(|e| format!("char array `{name}` is not UTF-16 code units: {e}"))?;
        Ok(MatValue::Char(String::from_utf16_lossy(&units)))
    }

    /// The object references of `d`, each counted as a value.
    fn references(&mut self, d: &Dataset, name: &str) -> R<Vec<ObjectReference1>> {
        let n = element_count(&d.shape(), &format!("`{name}`"))?;
        self.budget.take(n, name)?;
        d.read_raw::<ObjectReference1>()
            .map_err(|e| format!("`{name}` does not hold object references: {e}"))
    }

    /// The value a reference of `name` points to.
    fn referenced(&mut self, r: &ObjectReference1, name: &str, depth: usize) -> R<MatValue> {
        let node = match self.file.dereference(r) {
            Ok(ReferencedObject::Group(g)) => Node::Group(g),
            Ok(ReferencedObject::Dataset(d)) => Node::Dataset(d),
            Ok(ReferencedObject::Datatype(_)) => {
                return Err(format!("`{name}` refers to a datatype, not a value"))
            }
            Err(e) => return Err(format!("`{name}` holds a broken reference: {e}")),
        };
        self.value(&node, name, depth)
    }

    fn cell(&mut self, d: &Dataset, name: &str, depth: usize) -> R<MatValue> {
        let refs = self.references(d, name)?;
        let cells = refs
            .iter()
            .enumerate()
            .map(|(i, r)| self.referenced(r, &format!("{name}{{{}}}", i + 1), depth + 1))
            .collect::<R<Vec<_>>>()?;
        Ok(MatValue::Cell {
            dims: matlab_dims(&d.shape()),
            cells,
        })
    }

    /// A struct: a 1×1 struct's fields are its members; a struct array's fields
    /// are reference datasets without a `MATLAB_class`, one reference per element.
    fn structure(&mut self, g: &Group, name: &str, depth: usize) -> R<MatValue> {
        let fields = field_names(g).map_err(|e| format!("struct `{name}`: {e}"))?;
        let nodes = fields
            .iter()
            .map(|f| Node::open(g, f).map_err(|e| format!("struct `{name}`: {e}")))
            .collect::<R<Vec<_>>>()?;
        let reference_fields: Option<Vec<&Dataset>> = nodes
            .iter()
            .map(|n| match n {
                Node::Dataset(d) if is_reference_field(d) => Some(d),
                _ => None,
            })
            .collect();
        let datasets = match reference_fields {
            Some(d) if !d.is_empty() => d,
            _ => {
                let values = nodes
                    .iter()
                    .zip(&fields)
                    .map(|(n, f)| self.value(n, &format!("{name}.{f}"), depth + 1))
                    .collect::<R<Vec<_>>>()?;
                return Ok(MatValue::Struct {
                    dims: vec![1, 1],
                    fields,
                    elems: vec![values],
                });
            }
        };
        let mut dims = None;
        let mut columns = Vec::with_capacity(datasets.len());
        for (d, f) in datasets.iter().zip(&fields) {
            let field_dims = matlab_dims(&d.shape());
            if dims.get_or_insert_with(|| field_dims.clone()) != &field_dims {
                return Err(format!(
                    "struct array `{name}`: field `{f}` has dimensions {field_dims:?}, another field {dims:?}"
                ));
            }
            columns.push(self.references(d, &format!("{name}.{f}"))?);
        }
        let dims = dims.unwrap_or_else(|| vec![0, 0]);
        let count = columns.first().map_or(0, Vec::len);
        let mut elems = Vec::with_capacity(count);
        for i in 0..count {
            let mut values = Vec::with_capacity(fields.len());
            for (refs, f) in columns.iter().zip(&fields) {
                values.push(self.referenced(
                    &refs[i],
                    &format!("{name}({}).{f}", i + 1),
                    depth + 1,
                )?);
            }
            elems.push(values);
        }
        Ok(MatValue::Struct {
            dims,
            fields,
            elems,
        })
    }
}

/// Whether `d` is a field of a struct array: object references, no `MATLAB_class`.
fn is_reference_field(d: &Dataset) -> bool {
    string_attr(d, "MATLAB_class").is_none()
        && matches!(
            d.dtype().and_then(|t| t.to_descriptor()),
            Ok(TypeDescriptor::Reference(_))
        )
}

/// The field names of a struct group: the `MATLAB_fields` attribute (a
/// variable-length array of one-character strings per field) when it names the
/// group's members, else the members in the file's order.
fn field_names(g: &Group) -> R<Vec<String>> {
    let members = g
        .member_names()
        .map_err(|e| format!("cannot list the fields: {e}"))?;
    let declared: Option<Vec<String>> = g
        .attr("MATLAB_fields")
        .and_then(|a| a.read_raw::<VarLenArray<FixedAscii<1>>>())
        .ok()
        .map(|names| {
            names
                .iter()
                .map(|chars| chars.iter().map(|c| c.as_str()).collect())
                .collect()
        });
    Ok(match declared {
        Some(d) if !d.is_empty() && d.iter().all(|f| members.contains(f)) => d,
        _ => members,
    })
}
