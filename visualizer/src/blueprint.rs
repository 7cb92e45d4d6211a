//! The layout the viewer opens with, written as blueprint entities.
//!
//! Rerun 0.36's Rust builder (`rerun::blueprint::Blueprint`) lays out containers and views and
//! sets the panels, but cannot give a 3D view its camera (`EyeControls3D`, a view property that
//! only the Python builder exposes) nor a plot its legend and axes. So the blueprint is logged
//! here as the entities the viewer reads (the ones both builders write: `container/<id>`,
//! `view/<id>` with `ViewContents` and its properties, `viewport`, `*_panel`), and sent with
//! [`rerun::RecordingStream::send_blueprint`], as the builder does.

use anyhow::{Context as _, Result};
use rerun::blueprint::components::{
    BackgroundKind, ColumnShare, ContainerKind, Corner2D, Eye3DKind, IncludedContent, PanelState,
    QueryExpression, RootContainer, RowShare, TimelineName, ViewClass,
};
use rerun::external::re_log_types::{BlueprintActivationCommand, LogMsg, StoreId};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    Background, ContainerBlueprint, EyeControls3D, LineGrid3D, PanelBlueprint, PlotLegend,
    TimePanelBlueprint, ViewBlueprint, ViewContents, ViewportBlueprint,
};
use rerun::external::re_sdk_types::datatypes::{Float32, Uuid};

use crate::record::paths;

/// What the layout depends on.
#[derive(Debug, Clone)]
pub struct Layout {
    /// The radius (m) around the hand frame's origin that holds the hand and the object: the
    /// top view frames it.
    pub hand_radius: f32,
    /// A pipeline run (latency row, `time` timeline) rather than a plan (`step` only).
    pub run: bool,
    /// A spatial hand's plan: the hand and object seen from an oblique eye, not from the top.
    pub spatial: bool,
}

/// The views' names, as the viewer shows them (the tests look for them).
pub mod names {
    /// The hand and the object seen from above (paper Fig. 10).
    pub const HAND: &str = "Hand and object (top view)";
    /// A spatial hand and the object, seen from the side of the palm.
    pub const HAND_3D: &str = "Hand and object (3D; the axis of the turn in white)";
    /// The wrench space (paper Fig. 9).
    pub const WRENCH: &str = "Wrench space: GWS green, alpha OWS gold";
    /// The angles (paper Fig. 11).
    pub const ANGLES: &str = "Angles (deg): object (white), fingertips";
    /// The quality against the margin.
    pub const QUALITY: &str = "Quality: alpha* (green) vs alpha (red)";
    /// The plan phase.
    pub const PHASE: &str = "Phase: 1 rolling, 2 attach, 3 detach, 4 done";
    /// The pipeline's latency (runs only).
    pub const LATENCY: &str = "Latency (us)";
}

/// A deterministic blueprint id (a UUID's bytes) for part `n` of the layout.
fn id(n: u8) -> [u8; 16] {
    let mut b = *b"icrflow-layout-\0";
    b[15] = n;
    b
}

/// The UUID text of `bytes` (8-4-4-4-12 hex digits), as blueprint paths spell it.
fn uuid_text(bytes: [u8; 16]) -> String {
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

/// One part of the layout: a view or a container, by its blueprint path.
struct Part(String);

/// Logs the blueprint entities into a blueprint stream.
struct Writer<'a> {
    rec: &'a rerun::RecordingStream,
    next: u8,
}

impl Writer<'_> {
    fn fresh(&mut self) -> [u8; 16] {
        self.next += 1;
        id(self.next)
    }

    /// A view of class `class` (`3D`, `TimeSeries`) named `name` over `origin`, with its
    /// properties (archetype name, archetype).
    fn view(
        &mut self,
        class: &str,
        name: &str,
        origin: &str,
        properties: &[(&str, &dyn rerun::AsComponents)],
    ) -> Result<Part> {
        let path = format!("view/{}", uuid_text(self.fresh()));
        self.rec.log(
            format!("{path}/ViewContents"),
            &ViewContents::new([QueryExpression("$origin/**".into())]),
        )?;
        self.rec.log(
            path.as_str(),
            &ViewBlueprint::new(ViewClass(class.into()))
                .with_display_name(name)
                .with_space_origin(origin),
        )?;
        for (property, archetype) in properties {
            self.rec.log(format!("{path}/{property}"), *archetype)?;
        }
        Ok(Part(path))
    }

    /// A container of `kind` holding `parts` with these shares (of its columns for a
    /// horizontal one, rows for a vertical one).
    fn container(&mut self, kind: ContainerKind, parts: Vec<Part>, shares: &[f32]) -> Result<Part> {
        let bytes = self.fresh();
        let path = format!("container/{}", uuid_text(bytes));
        let mut arch = ContainerBlueprint::new(kind)
            .with_contents(parts.iter().map(|p| IncludedContent(p.0.clone().into())));
        arch = match kind {
            ContainerKind::Horizontal => {
                arch.with_col_shares(shares.iter().map(|&s| ColumnShare(Float32(s))))
            }
            _ => arch.with_row_shares(shares.iter().map(|&s| RowShare(Float32(s)))),
        };
        self.rec.log(path.as_str(), &arch)?;
        Ok(Part(path))
    }
}

/// A plot's legend: in the top-left corner (the curves start low at the left or are flat).
fn legend() -> PlotLegend {
    PlotLegend::new()
        .with_corner(Corner2D::LeftTop)
        .with_visible(true)
}

/// The blueprint's messages, for the application `app` and the recording `recording_id`.
pub fn messages(app: &'static str, recording_id: &str, layout: &Layout) -> Result<Vec<LogMsg>> {
    let (rec, storage) = rerun::RecordingStreamBuilder::new(app)
        .recording_id(format!("{recording_id}-blueprint"))
        .blueprint()
        .memory()
        .context("creating the blueprint")?;
    // The viewer reads blueprint entities on this timeline.
    rec.set_time_sequence("blueprint", 0);
    let mut w = Writer { rec: &rec, next: 0 };
    // The hand's plane is z = 0: the eye looks straight down -z at the hand frame's origin,
    // high enough to hold `hand_radius` in its field of view, y up on the screen.
    let r = layout.hand_radius.max(0.01);
    let top = EyeControls3D::new()
        .with_kind(Eye3DKind::Orbital)
        .with_position([0.0, 0.0, 2.15 * r])
        .with_look_target([0.0, 0.0, 0.0])
        .with_eye_up([0.0, 1.0, 0.0]);
    let no_grid = LineGrid3D::new().with_visible(false);
    let dark = Background::new(BackgroundKind::SolidColor).with_color(0x16181cff);
    // A spatial hand: from in front of the palm (+x), to the side (-y) and above (+z), the
    // object's centre and the palm's middle in view.
    let side = EyeControls3D::new()
        .with_kind(Eye3DKind::Orbital)
        .with_position([0.85 * r, -0.95 * r, 0.4 * r])
        .with_look_target([-0.15 * r, 0.0, -0.25 * r])
        .with_eye_up([0.0, 0.0, 1.0]);
    let (hand_name, eye) = if layout.spatial {
        (names::HAND_3D, &side)
    } else {
        (names::HAND, &top)
    };
    let hand = w.view(
        "3D",
        hand_name,
        paths::SCENE,
        &[
            ("EyeControls3D", eye),
            ("LineGrid3D", &no_grid),
            ("Background", &dark),
        ],
    )?;
    // The wrench space from an oblique eye, z (tau_z / rho) up.
    let oblique = EyeControls3D::new()
        .with_kind(Eye3DKind::Orbital)
        .with_position([1.9, -2.3, 1.5])
        .with_look_target([0.0, 0.0, 0.0])
        .with_eye_up([0.0, 0.0, 1.0]);
    let wrench = w.view(
        "3D",
        names::WRENCH,
        paths::WRENCH,
        &[("EyeControls3D", &oblique), ("Background", &dark)],
    )?;
    let legend = legend();
    let mut plots = vec![
        w.view(
            "TimeSeries",
            names::ANGLES,
            paths::ANGLES,
            &[("PlotLegend", &legend)],
        )?,
        w.view(
            "TimeSeries",
            names::QUALITY,
            paths::QUALITY,
            &[("PlotLegend", &legend)],
        )?,
        w.view(
            "TimeSeries",
            names::PHASE,
            paths::PHASE,
            &[("PlotLegend", &PlotLegend::new().with_visible(false))],
        )?,
    ];
    let mut shares = vec![3.0, 2.5, 1.2];
    if layout.run {
        plots.push(w.view(
            "TimeSeries",
            names::LATENCY,
            paths::LATENCY,
            &[("PlotLegend", &legend)],
        )?);
        shares.push(2.0);
    }
    let plots = w.container(ContainerKind::Vertical, plots, &shares)?;
    let root = w.container(
        ContainerKind::Horizontal,
        vec![hand, wrench, plots],
        &[1.15, 1.0, 1.0],
    )?;
    let root_id = id(w.next);
    debug_assert!(root.0.ends_with(&uuid_text(root_id)));
    rec.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(Uuid { bytes: root_id }))
            .with_auto_layout(false)
            .with_auto_views(false),
    )?;
    rec.log(
        "blueprint_panel",
        &PanelBlueprint::new().with_state(PanelState::Collapsed),
    )?;
    rec.log(
        "selection_panel",
        &PanelBlueprint::new().with_state(PanelState::Collapsed),
    )?;
    let timeline = if layout.run {
        crate::record::TIME
    } else {
        crate::record::STEP
    };
    rec.log(
        "time_panel",
        &TimePanelBlueprint::new()
            .with_state(PanelState::Collapsed)
            .with_timeline(TimelineName(timeline.into())),
    )?;
    rec.flush_blocking().context("writing the blueprint")?;
    Ok(storage.take())
}

/// Sends the blueprint to `rec` (before anything is logged), active and the application's
/// default, as `RecordingStreamBuilder::with_blueprint` does.
pub fn send(
    rec: &rerun::RecordingStream,
    app: &'static str,
    recording_id: &str,
    layout: &Layout,
) -> Result<()> {
    let msgs = messages(app, recording_id, layout)?;
    let blueprint_id: StoreId = msgs
        .iter()
        .find_map(|m| match m {
            LogMsg::SetStoreInfo(info) => Some(info.info.store_id.clone()),
            _ => None,
        })
        .context("the blueprint has no store info")?;
    rec.send_blueprint(
        msgs,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}
