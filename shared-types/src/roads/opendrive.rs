//! A road network as OpenDRIVE 1.4 text, and the check that a text from
//! elsewhere is an OpenDRIVE document at all (well-formed tags, an
//! `OpenDRIVE` root with a header and roads) before a world is built on it.

use std::fmt::Write;

use super::{
    Contact, Lane, Link, Road, RoadNetwork, Segment, Signal, SignalKind, LANE_WIDTH,
    SPEED_LIMIT_KMH,
};

/// The geographic reference of every simbus network: a transverse
/// Mercator projection of a sphere at 0°, 0° (see [`crate::gnss`]: what
/// CARLA 0.9.16's client computes on it is what it says). CARLA's client
/// warns when a map has none.
pub const GEO_REFERENCE: &str = "+proj=tmerc +lat_0=0 +lon_0=0 +k=0.9996 +x_0=0 +y_0=0 \
     +R=6378137 +units=m +no_defs";

/// The largest OpenDRIVE text [`check_opendrive`] reads, bytes.
pub const MAX_OPENDRIVE_BYTES: usize = 64 << 20;

/// Why a text is not an OpenDRIVE document.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OpenDriveError {
    /// Longer than [`MAX_OPENDRIVE_BYTES`].
    #[error("the OpenDRIVE text is {0} bytes, more than the {MAX_OPENDRIVE_BYTES} read")]
    TooLarge(usize),
    /// A tag, comment or section never closed.
    #[error("the OpenDRIVE text is not XML: {what} at byte {at} is never closed")]
    Unclosed {
        /// `a tag`, `a comment`, `a CDATA section`, `a declaration`.
        what: &'static str,
        /// Where it starts.
        at: usize,
    },
    /// An end tag that does not close the open element.
    #[error("the OpenDRIVE text is not XML: </{found}> at byte {at} closes <{expected}>")]
    Mismatched {
        /// The element open there (empty: none).
        expected: String,
        /// The end tag's name.
        found: String,
        /// Where the end tag starts.
        at: usize,
    },
    /// Elements left open at the end.
    #[error("the OpenDRIVE text is not XML: <{0}> is never closed")]
    Unterminated(String),
    /// Text outside the root element, or more than one root.
    #[error("the OpenDRIVE text is not XML: content outside the root element at byte {0}")]
    OutsideRoot(usize),
    /// The root is not `OpenDRIVE`.
    #[error("not an OpenDRIVE document: its root is <{0}>, not <OpenDRIVE>")]
    Root(String),
    /// No `header` or no `road` element.
    #[error("not an OpenDRIVE document: it has no <{0}>")]
    Missing(&'static str),
}

/// Checks that `text` is a well-formed XML document whose root is
/// `OpenDRIVE` and that holds a `header` and at least one `road`. (The
/// roads' geometry is CARLA's client's to read.)
///
/// # Errors
///
/// Returns [`OpenDriveError::TooLarge`] if `text` is longer than
/// [`MAX_OPENDRIVE_BYTES`]; [`OpenDriveError::Unclosed`],
/// [`OpenDriveError::Mismatched`], [`OpenDriveError::Unterminated`] or
/// [`OpenDriveError::OutsideRoot`] if it is not well-formed XML (each with the
/// byte offset or element where it breaks); [`OpenDriveError::Root`] if its
/// root element is not `OpenDRIVE`; and [`OpenDriveError::Missing`] if it has
/// no root, no `header` or no `road`.
pub fn check_opendrive(text: &str) -> Result<(), OpenDriveError> {
    if text.len() > MAX_OPENDRIVE_BYTES {
        return Err(OpenDriveError::TooLarge(text.len()));
    }
    let mut open: Vec<&str> = Vec::new();
    let (mut root, mut header, mut road) = (None, false, false);
    let mut at = 0;
    while let Some(lt) = text[at..].find('<').map(|i| at + i) {
        let outside = text[at..lt].trim();
        if open.is_empty() && !outside.is_empty() {
            return Err(OpenDriveError::OutsideRoot(at));
        }
        let rest = &text[lt..];
        let skip = |end: &str, what| {
            rest.find(end)
                .map(|i| lt + i + end.len())
                .ok_or(OpenDriveError::Unclosed { what, at: lt })
        };
        if rest.starts_with("<!--") {
            at = skip("-->", "a comment")?;
            continue;
        }
        if rest.starts_with("<![CDATA[") {
            at = skip("]]>", "a CDATA section")?;
            continue;
        }
        if rest.starts_with("<?") || rest.starts_with("<!") {
            at = skip(">", "a declaration")?;
            continue;
        }
        let end = tag_end(rest).ok_or(OpenDriveError::Unclosed {
            what: "a tag",
            at: lt,
        })?;
        let tag = &rest[1..end];
        at = lt + end + 1;
        if let Some(name) = tag.strip_prefix('/') {
            let name = name.trim();
            match open.pop() {
                Some(expected) if expected == name => {}
                expected => {
                    return Err(OpenDriveError::Mismatched {
                        expected: expected.unwrap_or_default().to_owned(),
                        found: name.to_owned(),
                        at: lt,
                    })
                }
            }
            continue;
        }
        let name = tag
            .split(|c: char| c.is_whitespace() || c == '/')
            .next()
            .unwrap_or("");
        if open.is_empty() {
            if root.is_some() {
                return Err(OpenDriveError::OutsideRoot(lt));
            }
            root = Some(name);
        }
        header |= name == "header";
        road |= name == "road";
        if !tag.ends_with('/') {
            open.push(name);
        }
    }
    if !text[at..].trim().is_empty() {
        return Err(OpenDriveError::OutsideRoot(at));
    }
    if let Some(name) = open.pop() {
        return Err(OpenDriveError::Unterminated(name.to_owned()));
    }
    match root {
        None => Err(OpenDriveError::Missing("OpenDRIVE")),
        Some(name) if name != "OpenDRIVE" => Err(OpenDriveError::Root(name.to_owned())),
        Some(_) if !header => Err(OpenDriveError::Missing("header")),
        Some(_) if !road => Err(OpenDriveError::Missing("road")),
        Some(_) => Ok(()),
    }
}

/// Where the tag starting `text` (at its `<`) ends: its `>`, outside
/// quoted attribute values.
fn tag_end(text: &str) -> Option<usize> {
    let mut quote = None;
    for (i, c) in text.char_indices().skip(1) {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '>') => return Some(i),
            (None, '<') => return None,
            _ => {}
        }
    }
    None
}

/// `text` with XML's special characters escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

impl RoadNetwork {
    /// The network as an OpenDRIVE 1.4 document: a header with a
    /// `geoReference` and the network's bounds, every road (lines and
    /// arcs, lanes of [`LANE_WIDTH`], a speed limit of
    /// [`SPEED_LIMIT_KMH`]), its signals, every junction (with the
    /// controllers of its lights) and the controllers themselves: one per
    /// light, named by the light's id.
    pub fn to_opendrive(&self) -> String {
        let mut out = String::with_capacity(2048 * self.roads.len());
        let [north, south, east, west] = self.bounds();
        let _ = write!(
            out,
            "<?xml version=\"1.0\" standalone=\"yes\"?>\n<OpenDRIVE>\n  \
             <header revMajor=\"1\" revMinor=\"4\" name=\"{}\" version=\"1\" \
             north=\"{north:.3}\" south=\"{south:.3}\" east=\"{east:.3}\" west=\"{west:.3}\" \
             vendor=\"simbus\">\n    <geoReference><![CDATA[{GEO_REFERENCE}]]></geoReference>\n  \
             </header>\n",
            escape(&self.name)
        );
        for road in &self.roads {
            write_road(&mut out, road, &self.signals);
        }
        for junction in &self.junctions {
            let _ = writeln!(
                out,
                "  <junction id=\"{0}\" name=\"junction {0}\">",
                junction.id
            );
            for (i, c) in junction.connections.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "    <connection id=\"{i}\" incomingRoad=\"{}\" connectingRoad=\"{}\" \
                     contactPoint=\"start\">\n      <laneLink from=\"{}\" to=\"-1\"/>\n    \
                     </connection>",
                    c.incoming, c.connecting, c.from_lane
                );
            }
            for light in self.lights_of(junction.id) {
                let _ = writeln!(
                    out,
                    "    <controller id=\"{}\" type=\"0\" sequence=\"{}\"/>",
                    light.id, light.pole
                );
            }
            out.push_str("  </junction>\n");
        }
        for light in self
            .signals
            .iter()
            .filter(|s| s.kind == SignalKind::TrafficLight)
        {
            let _ = writeln!(
                out,
                "  <controller id=\"{0}\" name=\"Controller {0}\" sequence=\"0\">\n    \
                 <control signalId=\"{0}\" type=\"0\"/>\n  </controller>",
                light.id
            );
        }
        out.push_str("</OpenDRIVE>\n");
        out
    }

    /// North, south, east and west bounds of the roads, metres.
    fn bounds(&self) -> [f64; 4] {
        let mut b = [f64::MIN, f64::MAX, f64::MIN, f64::MAX];
        for road in &self.roads {
            let length = road.length();
            for i in 0..=16 {
                let p = road.pose_at(length * f64::from(i) / 16.0);
                b = [b[0].max(p.y), b[1].min(p.y), b[2].max(p.x), b[3].min(p.x)];
            }
        }
        if self.roads.is_empty() {
            return [0.0; 4];
        }
        let margin = LANE_WIDTH;
        [b[0] + margin, b[1] - margin, b[2] + margin, b[3] - margin]
    }
}

/// One `<road>` element, with the signals of `signals` that stand on it.
fn write_road(out: &mut String, road: &Road, signals: &[Signal]) {
    let junction = road.junction.map_or(-1, i64::from);
    let _ = write!(
        out,
        "  <road name=\"road {0}\" length=\"{1:.6}\" id=\"{0}\" junction=\"{junction}\">\n    <link>\n",
        road.id,
        road.length()
    );
    write_links(out, road);
    let _ = write!(
        out,
        "    </link>\n    <type s=\"0.0\" type=\"town\">\n      \
         <speed max=\"{SPEED_LIMIT_KMH}\" unit=\"km/h\"/>\n    </type>\n    <planView>\n"
    );
    for ((s, pose), segment) in road.segment_starts().into_iter().zip(&road.segments) {
        let shape = match *segment {
            Segment::Line { .. } => "<line/>".to_owned(),
            Segment::Arc { curvature, .. } => format!("<arc curvature=\"{curvature:.9}\"/>"),
        };
        let _ = writeln!(
            out,
            "      <geometry s=\"{s:.6}\" x=\"{:.6}\" y=\"{:.6}\" hdg=\"{:.9}\" length=\"{:.6}\">{shape}</geometry>",
            pose.x,
            pose.y,
            pose.hdg,
            segment.length()
        );
    }
    out.push_str(
        "    </planView>\n    <elevationProfile>\n      \
         <elevation s=\"0.0\" a=\"0.0\" b=\"0.0\" c=\"0.0\" d=\"0.0\"/>\n    </elevationProfile>\n    \
         <lateralProfile/>\n    <lanes>\n      <laneSection s=\"0.0\">\n",
    );
    let connecting = road.junction.is_some();
    let side = |out: &mut String, name: &str, lanes: Vec<&Lane>| {
        if lanes.is_empty() {
            return;
        }
        let _ = writeln!(out, "        <{name}>");
        for lane in lanes {
            write_lane(out, lane, connecting);
        }
        let _ = writeln!(out, "        </{name}>");
    };
    side(
        out,
        "left",
        road.lanes.iter().filter(|l| l.id > 0).collect(),
    );
    let centre_mark = if connecting { "none" } else { "solid" };
    let _ = writeln!(
        out,
        "        <center>\n          <lane id=\"0\" type=\"none\" level=\"false\">\n            \
         <roadMark sOffset=\"0.0\" type=\"{centre_mark}\" weight=\"standard\" color=\"yellow\" width=\"0.15\"/>\n          \
         </lane>\n        </center>"
    );
    side(
        out,
        "right",
        road.lanes.iter().filter(|l| l.id < 0).collect(),
    );
    out.push_str("      </laneSection>\n    </lanes>\n");
    let mut on_road = signals.iter().filter(|s| s.road == road.id).peekable();
    if on_road.peek().is_some() {
        out.push_str("    <signals>\n");
        for signal in on_road {
            write_signal(out, signal);
        }
        out.push_str("    </signals>\n");
    }
    out.push_str("  </road>\n");
}

/// One `<signal>` element: its own lane its validity (so CARLA's client
/// finds it from that lane's waypoints), its head's height, and turned
/// (`hOffset`) to the heading of the traffic it speaks to.
fn write_signal(out: &mut String, signal: &Signal) {
    let (name, kind, subtype, value, unit) = match signal.kind {
        SignalKind::TrafficLight => ("Signal_3Light", "1000001", "-1".to_owned(), -1.0, ""),
        SignalKind::Stop => ("Sign_Stop", "206", "-1".to_owned(), -1.0, ""),
        SignalKind::SpeedLimit(kmh) => (
            "Sign_SpeedLimit",
            "274",
            kmh.to_string(),
            f64::from(kmh),
            "km/h",
        ),
    };
    let dynamic = if signal.kind == SignalKind::TrafficLight {
        "yes"
    } else {
        "no"
    };
    let turn = if signal.lane < 0 {
        0.0
    } else {
        std::f64::consts::PI
    };
    let [_, up, across] = signal.half_extents();
    let _ = writeln!(
        out,
        "      <signal s=\"{:.6}\" t=\"{:.6}\" id=\"{}\" name=\"{name} {}\" dynamic=\"{dynamic}\" \
         orientation=\"{}\" zOffset=\"{:.3}\" country=\"OpenDRIVE\" type=\"{kind}\" \
         subtype=\"{subtype}\" value=\"{value}\" unit=\"{unit}\" height=\"{:.3}\" width=\"{:.3}\" \
         text=\"\" hOffset=\"{turn:.9}\" pitch=\"0.0\" roll=\"0.0\">\n        \
         <validity fromLane=\"{lane}\" toLane=\"{lane}\"/>\n      </signal>",
        signal.s,
        signal.t,
        signal.id,
        signal.id,
        signal.orientation(),
        signal.height(),
        2.0 * up,
        2.0 * across,
        lane = signal.lane,
    );
}

/// A road's `predecessor` and `successor` elements.
fn write_links(out: &mut String, road: &Road) {
    for (what, link) in [
        ("predecessor", road.predecessor),
        ("successor", road.successor),
    ] {
        match link {
            Some(Link::Road { id, contact }) => {
                let contact = match contact {
                    Contact::Start => "start",
                    Contact::End => "end",
                };
                let _ = writeln!(
                    out,
                    "      <{what} elementType=\"road\" elementId=\"{id}\" contactPoint=\"{contact}\"/>"
                );
            }
            Some(Link::Junction(id)) => {
                let _ = writeln!(
                    out,
                    "      <{what} elementType=\"junction\" elementId=\"{id}\"/>"
                );
            }
            None => {}
        }
    }
}

/// One driving `<lane>` element.
fn write_lane(out: &mut String, lane: &Lane, connecting: bool) {
    let _ = writeln!(
        out,
        "          <lane id=\"{}\" type=\"driving\" level=\"false\">\n            <link>",
        lane.id
    );
    if let Some(id) = lane.predecessor {
        let _ = writeln!(out, "              <predecessor id=\"{id}\"/>");
    }
    if let Some(id) = lane.successor {
        let _ = writeln!(out, "              <successor id=\"{id}\"/>");
    }
    let mark = if connecting { "none" } else { "solid" };
    let _ = writeln!(
        out,
        "            </link>\n            \
         <width sOffset=\"0.0\" a=\"{LANE_WIDTH}\" b=\"0.0\" c=\"0.0\" d=\"0.0\"/>\n            \
         <roadMark sOffset=\"0.0\" type=\"{mark}\" weight=\"standard\" color=\"standard\" width=\"0.15\"/>\n          \
         </lane>"
    );
}
