//! The ground-station and plant frame decoder (`core::plant_link::FrameDecoder`) on any bytes: as one datagram,
//! and as a stream cut at fuzzer-chosen points. Nothing panics; the partial frame kept between reads
//! stays within one frame's size; the stream and the datagram agree on what a whole input holds; and
//! every frame decoded re-encodes to bytes that decode to the same message.
#![no_main]

use autopilot::core::plant_link::{DecodedFrame, FrameDecoder, encode_frame_v1, encode_frame_v2};
use libfuzzer_sys::fuzz_target;
use mavlink::MavlinkVersion;

/// The longest frame the decoder reads: 10 header, 3 more for a 32-bit system id, 255 payload, 2 CRC,
/// 13 signature bytes. It keeps less than that between reads.
const MAX_FRAME_BYTES: usize = 283;

fn reencode(frame: &DecodedFrame) -> Vec<u8> {
    match frame.version {
        MavlinkVersion::V1 => encode_frame_v1(frame.header, &frame.message).expect("a v1 frame fits v1"),
        MavlinkVersion::V2 => encode_frame_v2(frame.header, &frame.message),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&cut, bytes)) = data.split_first() else { return };
    let whole = FrameDecoder::new().decode_datagram(bytes);

    let mut stream = FrameDecoder::new();
    let mut frames = Vec::new();
    let step = usize::from(cut).max(1);
    for chunk in bytes.chunks(step) {
        frames.extend(stream.push(chunk));
        assert!(stream.pending_len() < MAX_FRAME_BYTES, "pending {} bytes", stream.pending_len());
    }
    frames.extend(stream.finish());
    assert_eq!(stream.pending_len(), 0);
    // Cut anywhere, a stream yields the frames the whole datagram holds.
    let bytes_of = |fs: &[DecodedFrame]| fs.iter().map(reencode).collect::<Vec<_>>();
    assert_eq!(bytes_of(&frames), bytes_of(&whole), "stream and datagram disagree");

    for frame in &whole {
        let again = reencode(frame);
        let decoded = FrameDecoder::new().decode_datagram(&again);
        assert_eq!(decoded.len(), 1, "a re-encoded frame decodes to one frame");
        assert_eq!(reencode(&decoded[0]), again, "re-encoding is stable");
        assert_eq!(decoded[0].header, frame.header);
    }
});
