//! A strict CDR (XCDR1, "plain CDR") decoder for `serde`.
//!
//! Decoding does not use the `cdr` crate's deserializer because that one
//! allocates a string's or byte sequence's claimed length before checking it
//! against the input: a corrupt sample claiming 4 GiB would be allocated
//! and zero-filled. Here every length is checked against the bytes left
//! first, and errors carry the field path and byte offset.

use crate::msg::CdrError;
use serde::de::{self, DeserializeOwned, DeserializeSeed, SeqAccess, Visitor};
use std::fmt;

/// Length of the encapsulation header before the CDR body.
const HEADER_LEN: usize = 4;

pub(crate) fn decode<M: DeserializeOwned>(
    bytes: &[u8],
    type_name: &'static str,
) -> std::result::Result<M, CdrError> {
    if bytes.len() < HEADER_LEN {
        return Err(CdrError::MissingHeader {
            type_name,
            len: bytes.len(),
        });
    }
    let id = u16::from_be_bytes([bytes[0], bytes[1]]);
    let big_endian = match id {
        0x0000 => true,
        0x0001 => false,
        _ => return Err(CdrError::Encapsulation { type_name, id }),
    };
    let mut reader = Reader {
        body: &bytes[HEADER_LEN..],
        pos: 0,
        big_endian,
    };
    M::deserialize(&mut reader).map_err(|e| CdrError::Decode {
        type_name,
        field: e.path(),
        offset: e.offset.unwrap_or(reader.pos) + HEADER_LEN,
        reason: e.reason,
    })
}

/// Reads the body; positions and alignment count from the byte after the
/// encapsulation header, as Fast-CDR's `reset_alignment()` does.
struct Reader<'de> {
    body: &'de [u8],
    pos: usize,
    big_endian: bool,
}

/// One step of a field path: a struct field or an array/sequence index.
#[derive(Debug)]
enum Segment {
    Field(&'static str),
    Index(usize),
}

/// Why decoding failed, where (an offset in the body, after the header), and
/// in which field (innermost first).
#[derive(Debug)]
pub(crate) struct DeError {
    reason: String,
    offset: Option<usize>,
    path: Vec<Segment>,
}

impl DeError {
    fn at(offset: usize, reason: String) -> DeError {
        DeError {
            reason,
            offset: Some(offset),
            path: Vec::new(),
        }
    }

    fn path(&self) -> String {
        if self.path.is_empty() {
            return "(message)".to_owned();
        }
        let mut s = String::new();
        for seg in self.path.iter().rev() {
            match seg {
                Segment::Field(name) => {
                    if !s.is_empty() {
                        s.push('.');
                    }
                    s.push_str(name);
                }
                Segment::Index(i) => s.push_str(&format!("[{i}]")),
            }
        }
        s
    }
}

impl fmt::Display for DeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path(), self.reason)
    }
}

impl std::error::Error for DeError {}

impl de::Error for DeError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        DeError {
            reason: msg.to_string(),
            offset: None,
            path: Vec::new(),
        }
    }
}

type Result<T> = std::result::Result<T, DeError>;

impl<'de> Reader<'de> {
    fn left(&self) -> usize {
        self.body.len() - self.pos
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'de [u8]> {
        if n > self.left() {
            return Err(DeError::at(
                self.pos,
                format!(
                    "{what} needs {n} bytes but only {} are left (truncated sample?)",
                    self.left()
                ),
            ));
        }
        let s = &self.body[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// Skips the padding before a primitive of `size` bytes.
    fn align(&mut self, size: usize) -> Result<()> {
        let pad = (size - self.pos % size) % size;
        self.take(pad, "alignment padding").map(|_| ())
    }

    fn read<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        self.align(N)?;
        let s = self.take(N, what)?;
        let mut b = [0u8; N];
        b.copy_from_slice(s);
        if self.big_endian {
            b.reverse();
        }
        // Now little endian.
        Ok(b)
    }

    fn read_u32(&mut self, what: &str) -> Result<u32> {
        self.read::<4>(what).map(u32::from_le_bytes)
    }

    /// A sequence or string length, checked against the bytes left: every
    /// element takes at least one byte, so a count above that is corrupt.
    fn read_len(&mut self, what: &str) -> Result<usize> {
        let at = self.pos;
        let n = self.read_u32(what)? as usize;
        if n > self.left() {
            return Err(DeError::at(
                at,
                format!(
                    "{what} claims {n} elements but only {} bytes are left",
                    self.left()
                ),
            ));
        }
        Ok(n)
    }

    fn read_str(&mut self) -> Result<&'de str> {
        let n = self.read_len("string length")?;
        let at = self.pos;
        let mut bytes = self.take(n, "string")?;
        // Like Fast-CDR, accept a missing NUL and a zero length.
        if let [head @ .., 0] = bytes {
            bytes = head;
        }
        std::str::from_utf8(bytes).map_err(|e| {
            DeError::at(
                at + e.valid_up_to(),
                format!("string is not valid UTF-8 ({e})"),
            )
        })
    }
}

macro_rules! primitive {
    ($method:ident, $visit:ident, $ty:ty, $n:literal) => {
        fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
            let b = self.read::<$n>(stringify!($ty))?;
            visitor.$visit(<$ty>::from_le_bytes(b))
        }
    };
}

macro_rules! unsupported {
    ($($method:ident),*) => {$(
        fn $method<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value> {
            Err(DeError::at(self.pos, format!(
                "{} is not a ROS 2 message type (CDR is not self-describing)",
                stringify!($method).trim_start_matches("deserialize_")
            )))
        }
    )*};
}

impl<'de> de::Deserializer<'de> for &mut Reader<'de> {
    type Error = DeError;

    primitive!(deserialize_i8, visit_i8, i8, 1);
    primitive!(deserialize_u8, visit_u8, u8, 1);
    primitive!(deserialize_i16, visit_i16, i16, 2);
    primitive!(deserialize_u16, visit_u16, u16, 2);
    primitive!(deserialize_i32, visit_i32, i32, 4);
    primitive!(deserialize_u32, visit_u32, u32, 4);
    primitive!(deserialize_f32, visit_f32, f32, 4);
    primitive!(deserialize_i64, visit_i64, i64, 8);
    primitive!(deserialize_u64, visit_u64, u64, 8);
    primitive!(deserialize_f64, visit_f64, f64, 8);

    unsupported!(
        deserialize_any,
        deserialize_char,
        deserialize_option,
        deserialize_map,
        deserialize_identifier,
        deserialize_ignored_any
    );

    fn deserialize_bool<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        let at = self.pos;
        match self.read::<1>("bool")? {
            [0] => visitor.visit_bool(false),
            [1] => visitor.visit_bool(true),
            [b] => Err(DeError::at(at, format!("bool must be 0 or 1, found {b}"))),
        }
    }

    fn deserialize_str<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        visitor.visit_borrowed_str(self.read_str()?)
    }

    fn deserialize_string<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        self.deserialize_str(visitor)
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        let n = self.read_len("uint8 sequence count")?;
        visitor.visit_borrowed_bytes(self.take(n, "uint8 sequence")?)
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        self.deserialize_bytes(visitor)
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        visitor.visit_unit()
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value> {
        visitor.visit_unit()
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value> {
        let n = self.read_len("sequence count")?;
        visitor.visit_seq(Elements {
            de: self,
            left: n,
            index: 0,
            fields: None,
        })
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, len: usize, visitor: V) -> Result<V::Value> {
        visitor.visit_seq(Elements {
            de: self,
            left: len,
            index: 0,
            fields: None,
        })
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        len: usize,
        visitor: V,
    ) -> Result<V::Value> {
        self.deserialize_tuple(len, visitor)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value> {
        visitor.visit_seq(Elements {
            de: self,
            left: fields.len(),
            index: 0,
            fields: Some(fields),
        })
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        name: &'static str,
        _variants: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value> {
        Err(DeError::at(
            self.pos,
            format!("enum {name} is not a ROS 2 message type"),
        ))
    }

    fn is_human_readable(&self) -> bool {
        false
    }
}

/// The elements of a struct (named fields), a fixed array or a sequence;
/// errors from inside get this element's name or index on their path.
struct Elements<'a, 'de> {
    de: &'a mut Reader<'de>,
    left: usize,
    index: usize,
    fields: Option<&'static [&'static str]>,
}

impl<'de> SeqAccess<'de> for Elements<'_, 'de> {
    type Error = DeError;

    fn next_element_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<Option<T::Value>> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        let index = self.index;
        self.index += 1;
        let start = self.de.pos;
        let fields = self.fields;
        seed.deserialize(&mut *self.de).map(Some).map_err(|mut e| {
            e.offset.get_or_insert(start);
            e.path.push(match fields.and_then(|f| f.get(index)) {
                Some(name) => Segment::Field(name),
                None => Segment::Index(index),
            });
            e
        })
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.left)
    }
}
