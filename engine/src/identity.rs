//! Bake identity: what a bake was made from (a scene, the bake's options), as a SHA-256 of a
//! canonical encoding. Resume, shard merge and `render --bake`-style reuse compare these hashes, so
//! they must mean the same thing across builds, platforms and refactors.
//!
//! The encoding is written by hand, value by value, never derived from `Debug` text or from Rust
//! names: a field rename, a new derive, a glam upgrade or another compiler leaves it unchanged.
//! Rules, in the order a value is written:
//! - integers as 8-byte little-endian (`u64`; `usize`, `u32` and `bool` widened to it);
//! - floats as the 4- or 8-byte little-endian bits of their IEEE 754 value (`f32::to_bits`,
//!   `f64::to_bits`): −0 and +0 differ, and no text formatting rounds anything;
//! - text as its UTF-8 byte length, then the bytes;
//! - a sequence as its length, then its elements; an absent optional as tag 0, a present one as
//!   tag 1 and the value;
//! - an enum as a tag number its `Canonical` impl fixes, then the variant's fields; a struct as
//!   its fields in the order its impl writes them.
//! - an option added after this version was fixed may be written after everything else, writing
//!   nothing for the value every earlier identity implied: those identities stand, and since the
//!   rest delimits itself the trailing value cannot be confused with another field.
//!
//! Each hash starts with a domain string and [`IDENTITY_VERSION`], so a scene hash and an options
//! hash never collide, and a change of the encoding is a new version, written into every bake's
//! manifest: a bake of another version is refused with a message, not silently misread.

use sha2::{Digest, Sha256};

/// The version of this encoding, written into each bake's provenance. Raise it whenever an impl
/// of [`Canonical`] writes anything differently.
pub const IDENTITY_VERSION: u32 = 1;

/// A SHA-256 being fed a canonical encoding.
pub struct Encoder {
    sha: Sha256,
}

impl Encoder {
    /// An encoder for one kind of identity (`domain`: "scene", "bake options"), with the encoding's
    /// version already written.
    pub fn new(domain: &str) -> Encoder {
        let mut encoder = Encoder { sha: Sha256::new() };
        encoder.text("lensmap identity");
        encoder.text(domain);
        encoder.u64(u64::from(IDENTITY_VERSION));
        encoder
    }

    /// Writes an unsigned integer.
    pub fn u64(&mut self, value: u64) -> &mut Encoder {
        self.sha.update(value.to_le_bytes());
        self
    }

    /// Writes an enum tag or a count (as a `u64`).
    pub fn tag(&mut self, tag: usize) -> &mut Encoder {
        self.u64(tag as u64)
    }

    /// Writes an `f32` as its bits.
    pub fn f32(&mut self, value: f32) -> &mut Encoder {
        self.sha.update(value.to_bits().to_le_bytes());
        self
    }

    /// Writes an `f64` as its bits.
    pub fn f64(&mut self, value: f64) -> &mut Encoder {
        self.sha.update(value.to_bits().to_le_bytes());
        self
    }

    /// Writes text: its byte length, then its UTF-8 bytes.
    pub fn text(&mut self, value: &str) -> &mut Encoder {
        self.tag(value.len());
        self.sha.update(value.as_bytes());
        self
    }

    /// Writes any [`Canonical`] value.
    pub fn value<T: Canonical + ?Sized>(&mut self, value: &T) -> &mut Encoder {
        value.encode(self);
        self
    }

    /// The hash, as 64 lowercase hex digits.
    pub fn finish(self) -> String {
        use std::fmt::Write as _;
        self.sha
            .finalize()
            .iter()
            .fold(String::with_capacity(64), |mut hex, byte| {
                // Writing into a String cannot fail.
                let _ = write!(hex, "{byte:02x}");
                hex
            })
    }
}

/// A value with a canonical encoding (see the module documentation for the rules).
pub trait Canonical {
    /// Writes the value into `encoder`.
    fn encode(&self, encoder: &mut Encoder);
}

/// The identity of `value` in `domain`: [`Encoder::new`], the value, [`Encoder::finish`].
pub fn identity<T: Canonical + ?Sized>(domain: &str, value: &T) -> String {
    let mut encoder = Encoder::new(domain);
    encoder.value(value);
    encoder.finish()
}

impl Canonical for u64 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.u64(*self);
    }
}

impl Canonical for u32 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.u64(u64::from(*self));
    }
}

impl Canonical for usize {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.tag(*self);
    }
}

impl Canonical for bool {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.u64(u64::from(*self));
    }
}

impl Canonical for f32 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f32(*self);
    }
}

impl Canonical for f64 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f64(*self);
    }
}

impl Canonical for str {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.text(self);
    }
}

impl Canonical for String {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.text(self);
    }
}

impl Canonical for glam::Vec2 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f32(self.x).f32(self.y);
    }
}

impl Canonical for glam::Vec3 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f32(self.x).f32(self.y).f32(self.z);
    }
}

impl Canonical for glam::DVec2 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f64(self.x).f64(self.y);
    }
}

impl Canonical for glam::DVec3 {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.f64(self.x).f64(self.y).f64(self.z);
    }
}

impl<T: Canonical, const N: usize> Canonical for [T; N] {
    fn encode(&self, encoder: &mut Encoder) {
        for item in self {
            item.encode(encoder);
        }
    }
}

impl<T: Canonical> Canonical for [T] {
    fn encode(&self, encoder: &mut Encoder) {
        encoder.tag(self.len());
        for item in self {
            item.encode(encoder);
        }
    }
}

impl<T: Canonical> Canonical for Vec<T> {
    fn encode(&self, encoder: &mut Encoder) {
        self.as_slice().encode(encoder);
    }
}

impl<T: Canonical> Canonical for Option<T> {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            None => {
                encoder.tag(0);
            }
            Some(value) => {
                encoder.tag(1).value(value);
            }
        }
    }
}

impl<T: Canonical + ?Sized> Canonical for &T {
    fn encode(&self, encoder: &mut Encoder) {
        (**self).encode(encoder);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SHA-256 of `bytes`, computed apart from the encoder.
    fn sha256_hex(bytes: &[u8]) -> String {
        Sha256::digest(bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// The bytes the encoder hashes for `new("d")` and then `value`, spelt out by the rules.
    fn prefix(domain: &str) -> Vec<u8> {
        let mut bytes = Vec::new();
        for text in ["lensmap identity", domain] {
            bytes.extend((text.len() as u64).to_le_bytes());
            bytes.extend(text.as_bytes());
        }
        bytes.extend(u64::from(IDENTITY_VERSION).to_le_bytes());
        bytes
    }

    #[test]
    fn the_encoding_is_the_documented_bytes() {
        let mut bytes = prefix("d");
        bytes.extend(1u64.to_le_bytes());
        bytes.extend(1.5f32.to_bits().to_le_bytes());
        bytes.extend((-0.0f32).to_bits().to_le_bytes());
        bytes.extend(2.0f32.to_bits().to_le_bytes());
        bytes.extend(1u64.to_le_bytes());
        bytes.extend(0.25f64.to_bits().to_le_bytes());
        bytes.extend(2u64.to_le_bytes());
        bytes.extend("ab".as_bytes());
        bytes.extend(0u64.to_le_bytes());
        let value = (
            vec![glam::Vec3::new(1.5, -0.0, 2.0)],
            Some(0.25f64),
            "ab",
            Option::<u32>::None,
        );
        let mut encoder = Encoder::new("d");
        encoder
            .value(&value.0)
            .value(&value.1)
            .value(value.2)
            .value(&value.3);
        assert_eq!(encoder.finish(), sha256_hex(&bytes));
    }

    #[test]
    fn values_that_print_alike_hash_apart() {
        // Debug text would print both zeros as 0.0 in some formats; bits do not.
        assert_ne!(identity("d", &0.0f32), identity("d", &-0.0f32));
        // A sequence's length is part of it: ["ab"] and ["a", "b"] differ.
        assert_ne!(
            identity("d", &vec!["ab".to_owned()]),
            identity("d", &vec!["a".to_owned(), "b".to_owned()])
        );
        // The domain separates kinds of identity.
        assert_ne!(identity("scene", &1u32), identity("bake options", &1u32));
    }
}
