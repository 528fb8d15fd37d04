//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! The serialized FMU state (fmi2SerializeFMUstate): self-contained (no pointers), versioned, and
//! checked on the way back in. Layout, all integers little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `RDRVFMU\0` |
//! | 2 | format version ([`FORMAT_VERSION`]) |
//! | 8 | interface fingerprint: a hash of the variable table (names, types) |
//! | 4 | payload length n |
//! | n | postcard encoding of [`Core`] with the model's state |
//! | 4 | CRC-32 of everything before it |
//!
//! Foreign, truncated or corrupted bytes fail one of these checks, and a payload that passes them
//! is still validated like any untrusted input (`Instance::snapshot_from_core`).

use crate::fmi::instance::{Core, Failure};
use crate::fmi::model::FmuModel;

const MAGIC: &[u8; 8] = b"RDRVFMU\0";
pub const FORMAT_VERSION: u16 = 1;
const HEADER: usize = 8 + 2 + 8 + 4;

/// FNV-1a over the variable names and types: a state from an FMU with another interface (another
/// model, or another version of this one) is refused instead of being misread. Computed once per
/// model.
pub fn interface_fingerprint<M: FmuModel>() -> u64 {
    *M::table().fingerprint.get_or_init(|| {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for v in M::table().variables {
            for b in v.name.bytes().chain([v.ty as u8, 0xff]) {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        h
    })
}

pub fn serialize<M: FmuModel>(core: &Core<M::State>) -> Result<Vec<u8>, Failure> {
    let payload = postcard::to_allocvec(core)
        .map_err(|e| Failure::error(format!("fmi2SerializeFMUstate: encoding failed: {e}")))?;
    let mut out = Vec::with_capacity(HEADER + payload.len() + 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&interface_fingerprint::<M>().to_le_bytes());
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

pub fn deserialize<M: FmuModel>(bytes: &[u8]) -> Result<Core<M::State>, Failure> {
    let fail = |why: &str| Failure::error(format!("fmi2DeSerializeFMUstate: rejected: {why}"));
    if bytes.len() < HEADER + 4 || &bytes[..8] != MAGIC {
        return Err(fail(&format!(
            "not a {} FMU state (magic number missing)",
            M::info().model_identifier
        )));
    }
    let version = u16::from_le_bytes([bytes[8], bytes[9]]);
    if version != FORMAT_VERSION {
        return Err(fail(&format!(
            "format version {version}, this FMU reads version {FORMAT_VERSION}"
        )));
    }
    let mut fp = [0u8; 8];
    fp.copy_from_slice(&bytes[10..18]);
    if u64::from_le_bytes(fp) != interface_fingerprint::<M>() {
        return Err(fail("saved by an FMU with a different variable interface"));
    }
    let n = u32::from_le_bytes([bytes[18], bytes[19], bytes[20], bytes[21]]) as usize;
    if bytes.len() != HEADER + n + 4 {
        return Err(fail(&format!(
            "length {} does not match the declared payload of {n} bytes",
            bytes.len()
        )));
    }
    let body = &bytes[..HEADER + n];
    let tail = &bytes[HEADER + n..];
    let crc = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    if crc != crc32fast::hash(body) {
        return Err(fail("checksum mismatch (corrupted bytes)"));
    }
    let (core, rest): (Core<M::State>, &[u8]) =
        postcard::take_from_bytes(&bytes[HEADER..HEADER + n])
            .map_err(|e| fail(&format!("payload does not decode: {e}")))?;
    if !rest.is_empty() {
        return Err(fail("trailing bytes in the payload"));
    }
    Ok(core)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmus::reciprocating_drive::ReciprocatingDrive as M;

    #[test]
    fn round_trip_and_every_kind_of_damage() {
        let mut core = Core::fresh::<M>();
        core.time = 1.25;
        core.values[0] = 0.5;
        let bytes = serialize::<M>(&core).unwrap();
        assert_eq!(deserialize::<M>(&bytes).unwrap(), core);
        // Truncation at every length.
        for n in 0..bytes.len() {
            assert!(deserialize::<M>(&bytes[..n]).is_err(), "truncated to {n}");
        }
        // A flipped bit anywhere.
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(deserialize::<M>(&b).is_err(), "bit flip at {i}");
        }
        // Foreign bytes.
        assert!(deserialize::<M>(b"definitely not an FMU state at all........").is_err());
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(deserialize::<M>(&longer).is_err());
    }
}
