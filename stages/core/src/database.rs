//! The view database: one histogram per training view (θ, φ), the palette
//! and parameters they were made with, and named extension sections that later
//! stages (recognition model, confidence network) store their own data in.
//!
//! File layout, little-endian:
//! ```text
//! magic     8 bytes  "ACCHDB\r\n" (the CR LF catches text-mode mangling)
//! version   u32      FORMAT_VERSION
//! length    u64      payload bytes
//! crc32     u32      of the payload
//! payload   object, training distance (m), palette, parameters, views,
//!           histograms, sections
//! ```

use crate::histogram::{HistogramKind, HistogramParams, OffsetSampling};
use crate::palette::{ColourSpace, Palette};
use crate::smooth::Smoothing;

/// Name of the section that holds the palette's smoothing
/// ([`Palette::smoothing`]); absent: none.
pub const SMOOTHING_SECTION: &str = "palette-smoothing";

/// Name of the (empty) section that says the database's colours were
/// learnt from the camera's own photographs, not from a mesh's rendered
/// views: they need no bridging to the camera's (the pose stage then takes
/// segmentation's region as it is).
pub const FROM_PHOTOGRAPHS_SECTION: &str = "from-photographs";
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"ACCHDB\r\n";
/// Version of the file layout this build reads and writes. Version 2: the
/// training distance is in metres (version 1 had object bounding radii).
pub const FORMAT_VERSION: u32 = 2;
const HEADER_LEN: usize = 8 + 4 + 8 + 4;

/// One training view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Elevation in degrees (90 = from above).
    pub theta_deg: f32,
    /// Azimuth in degrees, [0, 360).
    pub phi_deg: f32,
    /// Apparent object size in pixels (square root of the mask area), to
    /// estimate scale from a region of interest.
    pub size_px: f32,
    /// Where the object centre projects relative to the centre of the
    /// mask's bounding box, pixels at the training scale: a region's
    /// centre plus this is the centre's ray (a box seen from above shows
    /// its top nearer the camera, so its silhouette's centre is not its
    /// centre's projection). Zero when training did not know the centre.
    pub centre_offset_px: [f32; 2],
}

/// Why a database file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DbError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file does not start with the database magic.
    #[error("{path}: not an acch view database (bad magic bytes)")]
    NotADatabase {
        /// The file.
        path: PathBuf,
    },
    /// Written by another format version.
    #[error(
        "{path}: database format version {found} is not supported (this build reads version {supported}); retrain it with `acch train`"
    )]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The file is shorter than its header says.
    #[error("{path}: truncated: expected {expected} bytes, found {found}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Bytes the header announces.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The payload does not match its checksum.
    #[error("{path}: corrupt: checksum mismatch (stored {stored:08x}, computed {computed:08x})")]
    Checksum {
        /// The file.
        path: PathBuf,
        /// CRC-32 in the header.
        stored: u32,
        /// CRC-32 of the payload.
        computed: u32,
    },
    /// The payload is inconsistent.
    #[error("{path}: corrupt: {what}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
}

/// Histograms of every training view of one object.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewDatabase {
    /// Object name.
    pub object: String,
    /// The object's palette.
    pub palette: Palette,
    /// How the histograms were computed.
    pub params: HistogramParams,
    /// Camera distance of the training views to the object centre, metres:
    /// an object seen at distance `d` appears `train_distance_m / d` times
    /// its trained size, and a seed's translation is in metres.
    pub train_distance_m: f32,
    views: Vec<View>,
    histograms: Vec<f32>,
    /// Extension sections by name (for example "recognition", "confidence").
    pub sections: BTreeMap<String, Vec<u8>>,
}

impl ViewDatabase {
    /// An empty database.
    pub fn new(
        object: &str,
        palette: Palette,
        params: HistogramParams,
        train_distance_m: f32,
    ) -> Self {
        ViewDatabase {
            object: object.to_owned(),
            palette,
            params,
            train_distance_m,
            views: Vec::new(),
            histograms: Vec::new(),
            sections: BTreeMap::new(),
        }
    }

    /// Appends a view; views are kept in insertion order, which training
    /// makes θ-slice by θ-slice.
    pub fn push_view(&mut self, view: View, histogram: &[f32]) {
        assert_eq!(histogram.len(), self.params.len(), "histogram length");
        self.views.push(view);
        self.histograms.extend_from_slice(histogram);
    }

    /// The views.
    pub fn views(&self) -> &[View] {
        &self.views
    }

    /// The lowest and the highest elevation of the views, degrees (`None`:
    /// no views).
    pub fn theta_range_deg(&self) -> Option<(f32, f32)> {
        self.views.iter().fold(None, |range, v| {
            let (lo, hi) = range.unwrap_or((v.theta_deg, v.theta_deg));
            Some((lo.min(v.theta_deg), hi.max(v.theta_deg)))
        })
    }

    /// Histogram of view `i`.
    pub fn histogram(&self, i: usize) -> &[f32] {
        let n = self.params.len();
        &self.histograms[i * n..(i + 1) * n]
    }

    /// All histograms, view after view.
    pub fn histograms(&self) -> &[f32] {
        &self.histograms
    }

    /// The match-value response: `out[i]` = m(query, view i).
    pub fn response_into(&self, query: &[f32], out: &mut [f32]) {
        assert_eq!(out.len(), self.views.len(), "response length");
        let total: f32 = query.iter().sum();
        let n = self.params.len();
        for (o, h) in out.iter_mut().zip(self.histograms.chunks_exact(n)) {
            *o = if total > 0.0 {
                crate::histogram::intersection(query, h) / total
            } else {
                0.0
            };
        }
    }

    /// Median apparent object size over the training views, in pixels.
    pub fn median_size_px(&self) -> f32 {
        let mut s: Vec<f32> = self.views.iter().map(|v| v.size_px).collect();
        if s.is_empty() {
            return 0.0;
        }
        s.sort_by(f32::total_cmp);
        s[s.len() / 2]
    }

    /// Serialises into the file layout.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut p = Vec::with_capacity(self.histograms.len() * 4 + 4096);
        put_str(&mut p, &self.object);
        put_f32(&mut p, self.train_distance_m);
        p.push(self.palette.space().id());
        put_u16(&mut p, self.palette.len() as u16);
        put_f32(&mut p, self.palette.reject_distance());
        for c in self.palette.centres() {
            c.iter().for_each(|&v| put_f32(&mut p, v));
        }
        let q = &self.params;
        p.push(q.kind.id());
        put_u16(&mut p, q.colours);
        put_u16(&mut p, q.bins);
        put_f32(&mut p, q.r_min);
        put_f32(&mut p, q.r_max);
        put_u16(&mut p, q.stride);
        match q.sampling {
            OffsetSampling::Dense => {
                p.push(0);
                put_u16(&mut p, 0);
                put_u16(&mut p, 0);
            }
            OffsetSampling::Polar { rings, angles } => {
                p.push(1);
                put_u16(&mut p, rings);
                put_u16(&mut p, angles);
            }
        }
        put_u32(&mut p, self.views.len() as u32);
        for v in &self.views {
            put_f32(&mut p, v.theta_deg);
            put_f32(&mut p, v.phi_deg);
            put_f32(&mut p, v.size_px);
            put_f32(&mut p, v.centre_offset_px[0]);
            put_f32(&mut p, v.centre_offset_px[1]);
        }
        put_u32(&mut p, q.len() as u32);
        for &h in &self.histograms {
            put_f32(&mut p, h);
        }
        // The palette's smoothing travels as a section of its own, written
        // only when on, so that databases trained without it read as before.
        let smoothing = self.palette.smoothing();
        let smoothing_byte = [smoothing.id()];
        let smoothing_section =
            (smoothing != Smoothing::Off).then_some((SMOOTHING_SECTION, &smoothing_byte[..]));
        put_u32(
            &mut p,
            (self.sections.len() + smoothing_section.is_some() as usize) as u32,
        );
        let named = self.sections.iter().map(|(n, d)| (n.as_str(), &d[..]));
        for (name, data) in named.chain(smoothing_section) {
            put_str(&mut p, name);
            put_u64(&mut p, data.len() as u64);
            p.extend_from_slice(data);
        }
        let mut out = Vec::with_capacity(HEADER_LEN + p.len());
        out.extend_from_slice(MAGIC);
        put_u32(&mut out, FORMAT_VERSION);
        put_u64(&mut out, p.len() as u64);
        put_u32(&mut out, crc32fast::hash(&p));
        out.extend_from_slice(&p);
        out
    }

    /// Parses the file layout; `path` only names the source in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, DbError> {
        let path_buf = || path.to_path_buf();
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            return Err(DbError::NotADatabase { path: path_buf() });
        }
        if bytes.len() < HEADER_LEN {
            return Err(DbError::Truncated {
                path: path_buf(),
                expected: HEADER_LEN as u64,
                found: bytes.len() as u64,
            });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
        if version != FORMAT_VERSION {
            return Err(DbError::UnsupportedVersion {
                path: path_buf(),
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        let len = u64::from_le_bytes(bytes[12..20].try_into().unwrap());
        let stored = u32::from_le_bytes(bytes[20..24].try_into().unwrap());
        let found = (bytes.len() - HEADER_LEN) as u64;
        if found < len {
            return Err(DbError::Truncated {
                path: path_buf(),
                expected: HEADER_LEN as u64 + len,
                found: bytes.len() as u64,
            });
        }
        if found > len {
            return Err(DbError::Corrupt {
                path: path_buf(),
                what: format!("{} bytes after the payload", found - len),
            });
        }
        let payload = &bytes[HEADER_LEN..];
        let computed = crc32fast::hash(payload);
        if computed != stored {
            return Err(DbError::Checksum {
                path: path_buf(),
                stored,
                computed,
            });
        }
        parse_payload(payload).map_err(|what| DbError::Corrupt {
            path: path_buf(),
            what,
        })
    }

    /// Writes the database; the file appears whole or not at all (written
    /// beside it, then renamed), so a failed save never destroys an old one.
    pub fn save(&self, path: &Path) -> Result<(), DbError> {
        let io = |source| DbError::Io {
            path: path.to_path_buf(),
            source,
        };
        // A name of this writer's own: two processes or threads training
        // the same database on first use each rename a whole file (with
        // one shared name one renamed the other's, which then found none).
        static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(format!(".{}-{n}.partial", std::process::id()));
        let tmp = PathBuf::from(tmp);
        std::fs::write(&tmp, self.to_bytes()).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Reads a database file.
    pub fn load(path: &Path) -> Result<Self, DbError> {
        let bytes = std::fs::read(path).map_err(|source| DbError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }
}

fn put_u16(out: &mut Vec<u8>, v: u16) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s.as_bytes());
}

/// A bounds-checked reader: every read names what it was reading when the
/// payload ends early.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        if self.bytes.len() - self.pos < n {
            return Err(format!("payload ends inside {what}"));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.take(1, what)?[0])
    }
    fn u16(&mut self, what: &str) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2, what)?.try_into().unwrap()))
    }
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f32(&mut self, what: &str) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn finite(&mut self, what: &str) -> Result<f32, String> {
        let v = self.f32(what)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} is not a finite number"))
        }
    }
    fn string(&mut self, what: &str) -> Result<String, String> {
        let n = self.u32(what)? as usize;
        let b = self.take(n, what)?;
        String::from_utf8(b.to_vec()).map_err(|_| format!("{what} is not UTF-8"))
    }
}

fn parse_payload(payload: &[u8]) -> Result<ViewDatabase, String> {
    let mut r = Reader {
        bytes: payload,
        pos: 0,
    };
    let object = r.string("the object name")?;
    let train_distance_m = r.finite("the training distance")?;
    let space_id = r.u8("the colour space")?;
    let space = ColourSpace::from_id(space_id)
        .ok_or_else(|| format!("unknown colour space id {space_id}"))?;
    let n_colours = r.u16("the palette size")? as usize;
    let reject = r.f32("the palette rejection distance")?;
    let mut centres = Vec::with_capacity(n_colours.min(256));
    for _ in 0..n_colours {
        centres.push([
            r.finite("a palette colour")?,
            r.finite("a palette colour")?,
            r.finite("a palette colour")?,
        ]);
    }
    let palette =
        Palette::from_centres(space, centres, reject).map_err(|e| format!("palette: {e}"))?;
    let kind_id = r.u8("the histogram kind")?;
    let kind = HistogramKind::from_id(kind_id)
        .ok_or_else(|| format!("unknown histogram kind id {kind_id}"))?;
    let colours = r.u16("the histogram colours")?;
    let bins = r.u16("the histogram bins")?;
    let r_min = r.f32("r_min")?;
    let r_max = r.f32("r_max")?;
    let stride = r.u16("the stride")?;
    let sampling_id = r.u8("the offset sampling")?;
    let rings = r.u16("the sampling rings")?;
    let angles = r.u16("the sampling angles")?;
    let sampling = match sampling_id {
        0 => OffsetSampling::Dense,
        1 => OffsetSampling::Polar { rings, angles },
        other => return Err(format!("unknown offset sampling id {other}")),
    };
    let params = HistogramParams {
        kind,
        colours,
        bins,
        r_min,
        r_max,
        stride,
        sampling,
    };
    params.validate().map_err(|e| e.to_string())?;
    if colours as usize != palette.len() {
        return Err(format!(
            "histograms use {colours} colours but the palette has {}",
            palette.len()
        ));
    }
    let n_views = r.u32("the view count")? as usize;
    // Each view takes 20 bytes: refuse counts the payload cannot hold before
    // allocating for them.
    if n_views > (payload.len() - r.pos) / 20 {
        return Err(format!("view count {n_views} exceeds the payload"));
    }
    let mut views = Vec::with_capacity(n_views);
    for _ in 0..n_views {
        let theta_deg = r.finite("a view's theta")?;
        let phi_deg = r.finite("a view's phi")?;
        let size_px = r.finite("a view's size")?;
        let centre_offset_px = [
            r.finite("a view's centre offset")?,
            r.finite("a view's centre offset")?,
        ];
        if !(-1e-3..=90.001).contains(&theta_deg) {
            return Err(format!("view theta {theta_deg} is outside [0, 90]"));
        }
        views.push(View {
            theta_deg,
            phi_deg,
            size_px,
            centre_offset_px,
        });
    }
    let hist_len = r.u32("the histogram length")? as usize;
    if hist_len != params.len() {
        return Err(format!(
            "histogram length {hist_len} does not match the parameters ({})",
            params.len()
        ));
    }
    let raw = r.take(
        n_views
            .checked_mul(hist_len)
            .and_then(|n| n.checked_mul(4))
            .ok_or("histogram size overflows")?,
        "the histograms",
    )?;
    let histograms: Vec<f32> = raw
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    if histograms.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err("a histogram holds a negative or non-finite value".into());
    }
    let n_sections = r.u32("the section count")?;
    let mut sections = BTreeMap::new();
    for _ in 0..n_sections {
        let name = r.string("a section name")?;
        let len = r.u64("a section length")?;
        let len = usize::try_from(len).map_err(|_| format!("section '{name}' is too large"))?;
        let data = r.take(len, &format!("section '{name}'"))?;
        sections.insert(name, data.to_vec());
    }
    if r.pos != payload.len() {
        return Err(format!("{} unread bytes at the end", payload.len() - r.pos));
    }
    let palette = match sections.remove(SMOOTHING_SECTION).as_deref() {
        None => palette,
        Some(&[id]) => palette.with_smoothing(
            Smoothing::from_id(id).ok_or_else(|| format!("unknown palette smoothing {id}"))?,
        ),
        Some(_) => return Err("the palette smoothing section is not one byte".into()),
    };
    Ok(ViewDatabase {
        object,
        palette,
        params,
        train_distance_m,
        views,
        histograms,
        sections,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> ViewDatabase {
        let palette = Palette::from_centres(
            ColourSpace::Lab,
            vec![[50.0, 10.0, -10.0], [70.0, -20.0, 30.0]],
            12.5,
        )
        .unwrap();
        let params = HistogramParams {
            colours: 2,
            bins: 3,
            ..HistogramParams::default()
        };
        let mut db = ViewDatabase::new("thing", palette, params, 5.0);
        let n = params.len();
        db.push_view(
            View {
                theta_deg: 45.0,
                phi_deg: 10.0,
                size_px: 100.0,
                centre_offset_px: [0.5, -3.25],
            },
            &vec![1.0 / n as f32; n],
        );
        let mut h = vec![0.0; n];
        h[3] = 1.0;
        db.push_view(
            View {
                theta_deg: 90.0,
                phi_deg: 350.0,
                size_px: 120.0,
                centre_offset_px: [0.0, 0.0],
            },
            &h,
        );
        db.sections.insert("confidence".into(), vec![1, 2, 3]);
        db
    }

    #[test]
    fn writers_saving_one_path_at_once_each_leave_a_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("same.acchdb");
        let mut db = sample();
        db.sections.insert("big".into(), vec![7; 1 << 20]);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    for _ in 0..10 {
                        db.save(&path).expect("every save succeeds");
                    }
                });
            }
        });
        assert_eq!(ViewDatabase::load(&path).unwrap(), db);
    }

    #[test]
    fn the_theta_range_spans_the_views_and_is_none_without_any() {
        assert_eq!(sample().theta_range_deg(), Some((45.0, 90.0)));
        let empty = ViewDatabase::new("thing", sample().palette, sample().params, 5.0);
        assert_eq!(empty.theta_range_deg(), None);
    }

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.acchdb");
        let db = sample();
        db.save(&path).unwrap();
        let back = ViewDatabase::load(&path).unwrap();
        assert_eq!(back, db);
        assert_eq!(back.palette.index([0, 0, 0]), db.palette.index([0, 0, 0]));
        let mut r = vec![0.0; 2];
        back.response_into(back.histogram(1), &mut r);
        assert!((r[1] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn the_palette_smoothing_round_trips_and_is_off_in_older_files() {
        let p = Path::new("db.acchdb");
        let mut db = sample();
        db.palette = db.palette.clone().with_smoothing(Smoothing::Binomial);
        let bytes = db.to_bytes();
        let back = ViewDatabase::from_bytes(&bytes, p).unwrap();
        assert_eq!(back.palette.smoothing(), Smoothing::Binomial);
        assert_eq!(back, db);
        assert!(!back.sections.contains_key(SMOOTHING_SECTION));
        // Without smoothing no section is written: the bytes of a file
        // trained before it.
        let plain = sample();
        assert_eq!(plain.palette.smoothing(), Smoothing::Off);
        assert_eq!(
            plain.to_bytes().len() + SMOOTHING_SECTION.len() + 4 + 8 + 1,
            bytes.len()
        );
        let mut unknown = sample();
        unknown
            .sections
            .insert(SMOOTHING_SECTION.into(), vec![Smoothing::Binomial.id() + 7]);
        let e = ViewDatabase::from_bytes(&unknown.to_bytes(), p).unwrap_err();
        assert!(e.to_string().contains("smoothing"), "{e}");
        assert!(e.to_string().contains("db.acchdb"), "{e}");
    }

    #[test]
    fn corrupt_files_give_clear_errors() {
        let bytes = sample().to_bytes();
        let p = Path::new("db.acchdb");
        let err = |b: &[u8]| ViewDatabase::from_bytes(b, p).unwrap_err();

        assert!(matches!(err(b"PNG..."), DbError::NotADatabase { .. }));
        let mut v = bytes.clone();
        v[8] = 9;
        let e = err(&v);
        assert!(matches!(e, DbError::UnsupportedVersion { found: 9, .. }));
        assert!(e.to_string().contains("db.acchdb"), "{e}");
        for cut in [10, HEADER_LEN, bytes.len() - 1] {
            assert!(
                matches!(err(&bytes[..cut]), DbError::Truncated { .. }),
                "cut at {cut}"
            );
        }
        let mut v = bytes.clone();
        let last = v.len() - 5;
        v[last] ^= 0x40;
        assert!(matches!(err(&v), DbError::Checksum { .. }));
        let mut v = bytes.clone();
        v.push(0);
        assert!(matches!(err(&v), DbError::Corrupt { .. }));
        let missing = ViewDatabase::load(Path::new("/nonexistent/x.acchdb")).unwrap_err();
        assert!(matches!(missing, DbError::Io { .. }));
    }

    /// A payload whose checksum is right but whose content is not (a bug in
    /// a writer, or a crafted file) is refused, never a panic.
    #[test]
    fn inconsistent_payload_is_corrupt() {
        let bytes = sample().to_bytes();
        let mut payload = bytes[HEADER_LEN..].to_vec();
        // The palette size (after name and distance) claims 200 colours.
        let at = 4 + "thing".len() + 4 + 1;
        payload[at..at + 2].copy_from_slice(&200u16.to_le_bytes());
        let mut v = bytes[..HEADER_LEN].to_vec();
        v[20..24].copy_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        v.extend_from_slice(&payload);
        let e = ViewDatabase::from_bytes(&v, Path::new("x")).unwrap_err();
        assert!(matches!(e, DbError::Corrupt { .. }), "{e}");
    }
}
