//! `riseg::io::image::decode_flo` on arbitrary bytes (the `.flo` reader is this plus a
//! file read).
//!
//! Contract checked: no panic and no allocation beyond the header's checked size; an `Ok`
//! flow has sides in `1..=FLO_MAX_SIDE_PX` and encodes back to exactly the input bytes.

#![no_main]

use libfuzzer_sys::fuzz_target;
use riseg::io::image::{FLO_MAX_SIDE_PX, decode_flo, encode_flo};

fuzz_target!(|data: &[u8]| {
    if let Ok(flow) = decode_flo(data) {
        let side = 1..=FLO_MAX_SIDE_PX as usize;
        assert!(side.contains(&flow.width()) && side.contains(&flow.height()));
        let bytes = encode_flo(&flow).expect("a decoded flow encodes");
        assert!(bytes == data, "encode(decode(bytes)) differs from bytes");
    }
});
