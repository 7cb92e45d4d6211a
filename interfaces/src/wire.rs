//! The messages as bytes, for the Zenoh link that carries the loop's topics between hosts
//! (`icrflow-bridge`): the exact `#[repr(C)]` layout of the message (and of its slice items),
//! behind a fixed prefix that lets the receiver refuse what it cannot read. Nothing is
//! converted, so a message arrives as it was sent: sequence numbers, timestamps and trace
//! included.
//!
//! Layout (offsets in bytes; integers in the sender's byte order, which the receiver checks):
//!
//! | offset | field                                                      |
//! |--------|------------------------------------------------------------|
//! | 0      | magic `ICRW`                                               |
//! | 4      | byte-order mark `0x01020304` (u32)                         |
//! | 8      | [`crate::SCHEMA_VERSION`] of the sender (u32)               |
//! | 12     | [`crate::Kind`] (u32)                                      |
//! | 16     | size of the message (the slice topics' header) (u32)      |
//! | 20     | size of one slice item (0 without a slice) (u32)           |
//! | 24     | number of slice items (u32)                                |
//! | 28     | zero (u32)                                                 |
//! | 32     | the message, then the items                                |
//!
//! Both hosts must run the same schema version (the prefix says which) and the same byte
//! order (all the platforms the pipeline runs on are little-endian; a mismatch is refused).
//! A receiver still checks the message's header as it checks any input; the bytes decode to a
//! valid value whatever they are (the layouts have no padding and no field with invalid bit
//! patterns, which `zerocopy` checks at compile time).

use zerocopy::{FromBytes, Immutable, IntoBytes};

use crate::{Message, SCHEMA_VERSION};

/// The first four bytes.
pub const MAGIC: [u8; 4] = *b"ICRW";
/// The byte-order mark, as the sender wrote it.
const BYTE_ORDER: u32 = 0x0102_0304;
/// Bytes before the message.
pub const PREFIX: usize = 32;

/// Why bytes are not a message of the expected type.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    /// Too short for the prefix, or not the length the prefix announces.
    #[error("{got} bytes, expected {expected}")]
    Length {
        /// Bytes received.
        got: usize,
        /// Bytes expected.
        expected: usize,
    },
    /// Not a message of this format.
    #[error("not an icrflow wire message (magic {0:?})")]
    Magic([u8; 4]),
    /// The sender's byte order differs.
    #[error("the sender's byte order differs from this host's")]
    ByteOrder,
    /// Another schema version.
    #[error("schema version {got}, expected {expected}")]
    Schema {
        /// The sender's.
        got: u32,
        /// Ours.
        expected: u32,
    },
    /// Another kind of message.
    #[error("message kind {got}, expected {expected}")]
    Kind {
        /// The sender's.
        got: u32,
        /// The topic's.
        expected: u32,
    },
    /// The message or item size differs from this build's layout.
    #[error("{what} of {got} bytes, expected {expected}")]
    Size {
        /// Which size.
        what: &'static str,
        /// The sender's.
        got: u32,
        /// Ours.
        expected: u32,
    },
    /// More slice items than the topic carries.
    #[error("{got} items, at most {max}")]
    TooMany {
        /// Items announced.
        got: u32,
        /// The limit.
        max: usize,
    },
}

fn word(bytes: &[u8], at: usize) -> u32 {
    u32::from_ne_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

fn size_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// Writes `message` and `items` into `out` (cleared first; its capacity is reused).
pub fn encode<M, T>(message: &M, items: &[T], out: &mut Vec<u8>)
where
    M: Message + IntoBytes + Immutable,
    T: IntoBytes + Immutable,
{
    out.clear();
    out.extend_from_slice(&MAGIC);
    for w in [
        BYTE_ORDER,
        SCHEMA_VERSION,
        M::KIND as u32,
        size_u32(size_of::<M>()),
        if items.is_empty() {
            0
        } else {
            size_u32(size_of::<T>())
        },
        size_u32(items.len()),
        0,
    ] {
        out.extend_from_slice(&w.to_ne_bytes());
    }
    out.extend_from_slice(message.as_bytes());
    out.extend_from_slice(items.as_bytes());
}

/// Reads a message of type `M` and up to `max_items` items `T` (into `items`, cleared first)
/// from `bytes`, refusing anything that is not exactly that ([`WireError`]).
pub fn decode<M, T>(bytes: &[u8], max_items: usize, items: &mut Vec<T>) -> Result<M, WireError>
where
    M: Message + FromBytes,
    T: FromBytes,
{
    items.clear();
    if bytes.len() < PREFIX {
        return Err(WireError::Length {
            got: bytes.len(),
            expected: PREFIX,
        });
    }
    let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if magic != MAGIC {
        return Err(WireError::Magic(magic));
    }
    if word(bytes, 4) != BYTE_ORDER {
        return Err(WireError::ByteOrder);
    }
    let schema = word(bytes, 8);
    if schema != SCHEMA_VERSION {
        return Err(WireError::Schema {
            got: schema,
            expected: SCHEMA_VERSION,
        });
    }
    let kind = word(bytes, 12);
    if kind != M::KIND as u32 {
        return Err(WireError::Kind {
            got: kind,
            expected: M::KIND as u32,
        });
    }
    let size = word(bytes, 16);
    if size as usize != size_of::<M>() {
        return Err(WireError::Size {
            what: "message",
            got: size,
            expected: size_u32(size_of::<M>()),
        });
    }
    let (item_size, count) = (word(bytes, 20), word(bytes, 24));
    if count > 0 && item_size as usize != size_of::<T>() {
        return Err(WireError::Size {
            what: "slice item",
            got: item_size,
            expected: size_u32(size_of::<T>()),
        });
    }
    if count as usize > max_items {
        return Err(WireError::TooMany {
            got: count,
            max: max_items,
        });
    }
    let expected = PREFIX + size_of::<M>() + count as usize * size_of::<T>();
    if bytes.len() != expected {
        return Err(WireError::Length {
            got: bytes.len(),
            expected,
        });
    }
    let (body, rest) = bytes[PREFIX..].split_at(size_of::<M>());
    let length = |got| WireError::Length { got, expected };
    let message = M::read_from_bytes(body).map_err(|_| length(bytes.len()))?;
    if size_of::<T>() > 0 {
        items.reserve(count as usize);
        for chunk in rest.chunks_exact(size_of::<T>()) {
            items.push(T::read_from_bytes(chunk).map_err(|_| length(bytes.len()))?);
        }
    }
    Ok(message)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Facet, GraspState, Header, Kind, PlanStepHeader, WrenchSpaceHeader};

    fn wrench() -> (WrenchSpaceHeader, Vec<Facet>) {
        let mut h = WrenchSpaceHeader {
            header: Header::new(Kind::WrenchSpace, 42, 41, 1_000),
            force_closure: 1,
            dim: 3,
            quality: 0.123456789,
            epsilon: -0.5,
            alpha: 0.1,
        };
        h.header.trace.push(1_000);
        h.header.trace.push(2_000);
        let facets = (0..5)
            .map(|i| Facet {
                normal: [i as f64, 0.5, -1.0, f64::MIN_POSITIVE, 1e300, 0.0],
                offset: 1.0 / (i as f64 + 3.0),
            })
            .collect();
        (h, facets)
    }

    #[test]
    fn a_message_and_its_slice_arrive_bit_for_bit() {
        let (h, facets) = wrench();
        let mut bytes = Vec::new();
        encode(&h, &facets, &mut bytes);
        assert_eq!(
            bytes.len(),
            PREFIX + size_of::<WrenchSpaceHeader>() + 5 * 56
        );
        let mut got = vec![Facet::default()];
        let back: WrenchSpaceHeader = decode(&bytes, 4096, &mut got).unwrap();
        assert_eq!(back, h);
        assert_eq!(got, facets);
        // Without a slice.
        let g = GraspState {
            rotation: 1.25,
            ..Default::default()
        };
        encode(&g, &[] as &[u32], &mut bytes);
        let back: GraspState = decode(&bytes, 0, &mut Vec::<u32>::new()).unwrap();
        assert_eq!(back, g);
    }

    #[test]
    fn whatever_is_not_exactly_the_expected_message_is_refused_by_name() {
        let (h, facets) = wrench();
        let mut bytes = Vec::new();
        encode(&h, &facets, &mut bytes);
        let mut items = Vec::<Facet>::new();
        let mut try_decode =
            |b: &[u8]| decode::<WrenchSpaceHeader, Facet>(b, 4096, &mut items).unwrap_err();
        assert!(matches!(try_decode(&[]), WireError::Length { .. }));
        assert!(matches!(
            try_decode(b"{\"x\": 1}"),
            WireError::Length { .. }
        ));
        assert!(matches!(
            try_decode(&bytes[..bytes.len() - 1]),
            WireError::Length { .. }
        ));
        let corrupt = |at: usize, value: u32| {
            let mut b = bytes.clone();
            b[at..at + 4].copy_from_slice(&value.to_ne_bytes());
            b
        };
        assert!(matches!(try_decode(&corrupt(0, 7)), WireError::Magic(_)));
        assert_eq!(
            try_decode(&corrupt(4, BYTE_ORDER.swap_bytes())),
            WireError::ByteOrder
        );
        assert_eq!(
            try_decode(&corrupt(8, SCHEMA_VERSION + 1)),
            WireError::Schema {
                got: SCHEMA_VERSION + 1,
                expected: SCHEMA_VERSION
            }
        );
        assert!(matches!(
            try_decode(&corrupt(12, Kind::PlanStep as u32)),
            WireError::Kind { .. }
        ));
        assert!(matches!(
            try_decode(&corrupt(16, 8)),
            WireError::Size {
                what: "message",
                ..
            }
        ));
        assert!(matches!(
            try_decode(&corrupt(20, 8)),
            WireError::Size {
                what: "slice item",
                ..
            }
        ));
        assert!(matches!(
            try_decode(&corrupt(24, 6)),
            WireError::Length { .. }
        ));
        assert!(matches!(
            decode::<WrenchSpaceHeader, Facet>(&bytes, 4, &mut Vec::new()),
            Err(WireError::TooMany { got: 5, max: 4 })
        ));
        // The right bytes read as another message type are refused by kind.
        assert!(matches!(
            decode::<PlanStepHeader, u32>(&bytes, 4096, &mut Vec::new()),
            Err(WireError::Kind { .. })
        ));
    }
}
