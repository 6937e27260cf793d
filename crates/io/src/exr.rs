//! OpenEXR depth maps: 32-bit float scanline images, uncompressed.

use std::collections::HashSet;
use std::io::Cursor;
use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image as ExrImage, Layer,
    LayerAttributes, LineOrder, MetaData, SmallVec, Text, WritableImage,
};
use stereo_image::Image;

use crate::{format_err, write_atomic, Error};

fn exr_err(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(source) => Error::Io { path: path.to_path_buf(), source },
        exr::error::Error::NotSupported(m) => format_err(path, format!("unsupported EXR: {m}")),
        exr::error::Error::Invalid(m) => format_err(path, format!("invalid EXR file: {m}")),
        exr::error::Error::Aborted => format_err(path, "EXR reading aborted"),
    }
}

/// Writes a single-part scanline EXR with the given named 32-bit float channels (e.g.
/// `("Z", depth)`), uncompressed, atomically. (ZIP, OpenEXR's usual lossless compression, saved
/// 12–36 % of a float depth map's size, whose low mantissa bytes do not compress, and took 25–60
/// times as long to write: on a small pair longer than the match itself, docs/perf-notes.md.)
/// All channels must have the same non-zero size and distinct, non-empty ASCII names.
pub fn write_exr(path: &Path, channels: &[(&str, &Image<f32>)]) -> Result<(), Error> {
    let Some(&(_, first)) = channels.first() else {
        return Err(format_err(path, "cannot write an EXR without channels"));
    };
    let (width, height) = first.size();
    if width == 0 || height == 0 {
        return Err(format_err(path, format!("cannot write a {width}x{height} EXR (empty image)")));
    }
    let mut seen = HashSet::new();
    let mut list = SmallVec::new();
    for &(name, image) in channels {
        if image.size() != (width, height) {
            let (w, h) = image.size();
            return Err(format_err(
                path,
                format!(
                    "EXR channel {name:?} is {w}x{h} but channel {:?} is {width}x{height}",
                    channels[0].0
                ),
            ));
        }
        if !seen.insert(name) {
            return Err(format_err(path, format!("duplicate EXR channel name {name:?}")));
        }
        let text =
            Text::new_or_none(name).filter(|_| !name.is_empty() && name.is_ascii()).ok_or_else(|| {
                format_err(path, format!("invalid EXR channel name {name:?} (want non-empty ASCII)"))
            })?;
        list.push(AnyChannel::new(text, FlatSamples::F32(image.as_slice().to_vec())));
    }
    let encoding = Encoding {
        compression: Compression::Uncompressed,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new((width, height), LayerAttributes::default(), encoding, AnyChannels::sort(list));
    let mut buffer = Cursor::new(Vec::new());
    ExrImage::from_layer(layer).write().to_buffered(&mut buffer).map_err(|e| exr_err(path, e))?;
    write_atomic(path, buffer.get_ref())
}

/// The channel names of the first part of an EXR file (as stored: sorted alphabetically).
pub fn exr_channel_names(path: &Path) -> Result<Vec<String>, Error> {
    let meta = MetaData::read_from_file(path, false).map_err(|e| exr_err(path, e))?;
    let header = meta.headers.first().ok_or_else(|| format_err(path, "EXR file has no parts"))?;
    Ok(header.channels.list.iter().map(|c| c.name.to_string()).collect())
}

/// Reads the channel `name` of the first flat (non-deep) layer of an EXR file as f32 (f16 and
/// u32 samples are converted), top row first.
pub fn read_exr_channel(path: &Path, name: &str) -> Result<Image<f32>, Error> {
    if path.is_dir() {
        return Err(format_err(path, "is a directory, not an EXR file"));
    }
    let image = exr::prelude::read_first_flat_layer_from_file(path).map_err(|e| exr_err(path, e))?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let list = &layer.channel_data.list;
    let Some(channel) = list.iter().find(|c| c.name.eq(name)) else {
        let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
        return Err(format_err(path, format!("no EXR channel {name:?} (channels: {})", names.join(", "))));
    };
    let data: Vec<f32> = channel.sample_data.values_as_f32().collect();
    Image::from_vec(width, height, data).map_err(|e| format_err(path, format!("EXR channel {name:?}: {e}")))
}
