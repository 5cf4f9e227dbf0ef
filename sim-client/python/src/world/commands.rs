//! The command classes: one per wire command ([`shared_types::CommandKind`]),
//! each deriving from `simbus.Command`, with CARLA's names where CARLA has
//! the command (`simbus.SetTargetVelocity(id, (1, 0, 0))`). Values are
//! checked as a command is built (wrong types: `TypeError`; NaN, infinite
//! or beyond `f32`: `ValueError`), so nothing bad is ever sent; ranges
//! (sizes, positions, throttle) are the server's to judge, per command.

use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyString};
use pyo3::PyClass;
use shared_types::{ActorKind, Command as Wire, CommandKind};

/// A `name` of `N` numbers (any sequence: tuple, list, numpy array), each
/// finite as an `f32`.
pub(super) fn numbers<const N: usize>(name: &str, value: &Bound<'_, PyAny>) -> PyResult<[f32; N]> {
    let wrong = || {
        let kind = value
            .get_type()
            .name()
            .map_or_else(|_| "?".to_owned(), |n| n.to_string());
        PyTypeError::new_err(format!(
            "{name} must be a sequence of {N} numbers, got {kind}"
        ))
    };
    if value.is_instance_of::<PyString>() {
        return Err(wrong());
    }
    let values: Vec<f64> = value.extract().map_err(|_| wrong())?;
    let values: [f64; N] = values.try_into().map_err(|v: Vec<f64>| {
        PyValueError::new_err(format!("{name} must have {N} values, got {}", v.len()))
    })?;
    let mut out = [0.0; N];
    for (slot, value) in out.iter_mut().zip(values) {
        *slot = finite(name, value)?;
    }
    Ok(out)
}

/// `value` as an `f32`, refused when NaN, infinite or beyond `f32`'s range.
pub(super) fn finite(name: &str, value: f64) -> PyResult<f32> {
    let single = value as f32;
    if single.is_finite() {
        Ok(single)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be finite (within +-3.4e38), got {value:?}"
        )))
    }
}

/// An actor id: a non-negative integer (not a bool).
pub(super) fn actor_id(value: &Bound<'_, PyAny>) -> PyResult<u64> {
    if value.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err("actor_id must be an int, got bool"));
    }
    value.extract::<u64>().map_err(|e| {
        if e.is_instance_of::<PyOverflowError>(value.py()) {
            PyValueError::new_err(format!("actor_id must be in 0..2**64, got {value}"))
        } else {
            let kind = value
                .get_type()
                .name()
                .map_or_else(|_| "?".to_owned(), |n| n.to_string());
            PyTypeError::new_err(format!("actor_id must be an int, got {kind}"))
        }
    })
}

pub(super) fn triple(v: [f32; 3]) -> (f32, f32, f32) {
    (v[0], v[1], v[2])
}

fn quad(v: [f32; 4]) -> (f32, f32, f32, f32) {
    (v[0], v[1], v[2], v[3])
}

/// The Python object of command `sub` sending `wire`.
pub(super) fn subclass<T: PyClass<BaseType = Command>>(
    sub: T,
    wire: Wire,
) -> PyClassInitializer<T> {
    PyClassInitializer::from(Command { wire }).add_subclass(sub)
}

pub(super) fn flag(wire: &Wire) -> bool {
    wire.flags & Wire::ON != 0
}

/// A command for `apply_batch` / `apply_batch_sync`: build one of its
/// subclasses (`SpawnActor`, `DestroyActor`, `SetTransform`,
/// `SetTargetVelocity`, `ApplyForce`, `ApplyImpulse`, `ApplyTorque`,
/// `SetSimulatePhysics`, `SetEnableGravity`, `ApplyVehicleControl`).
#[pyclass(module = "simbus", subclass, frozen, eq)]
#[derive(Debug, PartialEq)]
pub(crate) struct Command {
    pub(super) wire: Wire,
}

#[pymethods]
impl Command {
    /// The actor the command acts on (`None` for a spawn).
    #[getter]
    fn actor_id(&self) -> Option<u64> {
        let spawns = CommandKind::from_u32(self.wire.kind).is_some_and(|k| k.spawns());
        (!spawns).then_some(self.wire.actor)
    }

    fn __repr__(&self) -> String {
        describe(&self.wire)
    }
}

/// A command as the Python expression that builds it.
pub(super) fn describe(w: &Wire) -> String {
    let (id, v, r, p) = (w.actor, w.vector, w.rotation, w.params);
    let Some(kind) = CommandKind::from_u32(w.kind) else {
        return format!("Command(kind={})", w.kind);
    };
    match kind {
        CommandKind::SpawnBox => format!(
            "SpawnActor('box', at={:?}, rotation={:?}, half_extents={:?})",
            triple(v),
            quad(r),
            (p[0], p[1], p[2])
        ),
        CommandKind::SpawnSphere => format!(
            "SpawnActor('sphere', at={:?}, rotation={:?}, radius={:?})",
            triple(v),
            quad(r),
            p[0]
        ),
        CommandKind::SpawnCapsule => format!(
            "SpawnActor('capsule', at={:?}, rotation={:?}, radius={:?}, half_height={:?})",
            triple(v),
            quad(r),
            p[0],
            p[1]
        ),
        CommandKind::SpawnVehicle => {
            format!(
                "SpawnActor('vehicle', at={:?}, rotation={:?})",
                triple(v),
                quad(r)
            )
        }
        CommandKind::SpawnWalker => format!(
            "SpawnActor('walker', at={:?}, rotation={:?}, radius={:?}, half_height={:?})",
            triple(v),
            quad(r),
            p[0],
            p[1]
        ),
        CommandKind::WalkerControl => format!(
            "ApplyWalkerControl({id}, direction={:?}, speed={:?}, jump={})",
            triple(v),
            p[0],
            py_bool(flag(w))
        ),
        CommandKind::Destroy => format!("DestroyActor({id})"),
        CommandKind::SetTransform => {
            format!(
                "SetTransform({id}, position={:?}, rotation={:?})",
                triple(v),
                quad(r)
            )
        }
        CommandKind::SetTargetVelocity => format!(
            "SetTargetVelocity({id}, velocity={:?}, angular_velocity={:?})",
            triple(v),
            (r[0], r[1], r[2])
        ),
        CommandKind::ApplyForce => format!("ApplyForce({id}, force={:?})", triple(v)),
        CommandKind::ApplyImpulse => format!("ApplyImpulse({id}, impulse={:?})", triple(v)),
        CommandKind::ApplyTorque => format!("ApplyTorque({id}, torque={:?})", triple(v)),
        CommandKind::SetPhysics => format!("SetSimulatePhysics({id}, {})", py_bool(flag(w))),
        CommandKind::SetGravity => format!("SetEnableGravity({id}, {})", py_bool(flag(w))),
        CommandKind::ConstantVelocity => match flag(w) {
            true => format!("ConstantVelocity({id}, velocity={:?})", triple(v)),
            false => format!("ConstantVelocity({id}, velocity=None)"),
        },
        CommandKind::SetSun => format!("SetSun(azimuth={:?}, altitude={:?})", p[0], p[1]),
        CommandKind::VehicleControl => format!(
            "ApplyVehicleControl({id}, throttle={:?}, steer={:?}, brake={:?}, hand_brake={}{})",
            p[0],
            p[1],
            p[2],
            py_bool(flag(w)),
            if w.flags & Wire::REVERSE != 0 {
                ", reverse=True"
            } else {
                ""
            }
        ),
        CommandKind::VehicleAckermann => format!(
            "ApplyVehicleAckermannControl({id}, steer={:?}, steer_speed={:?}, speed={:?}, \
             acceleration={:?})",
            p[0], p[1], p[2], p[3]
        ),
        CommandKind::TrafficLightState
        | CommandKind::TrafficLightTimes
        | CommandKind::FreezeTrafficLights
        | CommandKind::ResetTrafficLights => super::light_commands::describe(kind, w),
    }
}

pub(super) fn py_bool(value: bool) -> &'static str {
    if value {
        "True"
    } else {
        "False"
    }
}

/// The spawn command for `kind` with its sizes (defaults: box half extents
/// 0.5 m, sphere radius 0.5 m, capsule radius 0.3 m and half height 0.5 m,
/// walker radius 0.25 m and half height 0.9 m).
pub(super) fn spawn_command(
    kind: &str,
    at: Option<&Bound<'_, PyAny>>,
    rotation: Option<&Bound<'_, PyAny>>,
    half_extents: Option<&Bound<'_, PyAny>>,
    radius: Option<f64>,
    half_height: Option<f64>,
) -> PyResult<Wire> {
    let at = at.map_or(Ok([0.0, 5.0, 0.0]), |a| numbers("at", a))?;
    let name = kind;
    let kind = ActorKind::from_name(name).filter(|k| *k != ActorKind::Static);
    let not_for = |what: &str, kind: ActorKind| {
        PyValueError::new_err(format!("{what} does not apply to a {}", kind.name()))
    };
    let mut wire = match kind {
        Some(ActorKind::Box) => {
            if radius.is_some() || half_height.is_some() {
                return Err(not_for("radius / half_height", ActorKind::Box));
            }
            let half = half_extents.map_or(Ok([0.5; 3]), |h| numbers("half_extents", h))?;
            Wire::spawn_box(at, half)
        }
        Some(k @ (ActorKind::Sphere | ActorKind::Capsule)) => {
            if half_extents.is_some() {
                return Err(not_for("half_extents", k));
            }
            let r = finite(
                "radius",
                radius.unwrap_or(if k == ActorKind::Sphere { 0.5 } else { 0.3 }),
            )?;
            match (k, half_height) {
                (ActorKind::Sphere, Some(_)) => return Err(not_for("half_height", k)),
                (ActorKind::Sphere, None) => Wire::spawn_sphere(at, r),
                (_, h) => Wire::spawn_capsule(at, r, finite("half_height", h.unwrap_or(0.5))?),
            }
        }
        Some(ActorKind::Walker) => {
            if half_extents.is_some() {
                return Err(not_for("half_extents", ActorKind::Walker));
            }
            Wire::spawn_walker(
                at,
                finite("radius", radius.unwrap_or(0.25))?,
                finite("half_height", half_height.unwrap_or(0.9))?,
            )
        }
        Some(ActorKind::Vehicle) => {
            if half_extents.is_some() || radius.is_some() || half_height.is_some() {
                return Err(not_for("a size", ActorKind::Vehicle));
            }
            Wire::spawn_vehicle(at)
        }
        _ => {
            return Err(PyValueError::new_err(format!(
                "unknown actor kind '{name}': expected 'box', 'sphere', 'capsule', 'vehicle' \
                 or 'walker'"
            )))
        }
    };
    if let Some(rotation) = rotation {
        wire.rotation = numbers("rotation", rotation)?;
    }
    Ok(wire)
}

/// Spawns an actor: `kind` is `"box"`, `"sphere"`, `"capsule"`,
/// `"vehicle"` or `"walker"`, `at` its position (x, y, z; Y up; default
/// (0, 5, 0)), `rotation` a quaternion (x, y, z, w). Sizes: `half_extents`
/// (box, default 0.5 m each), `radius` (sphere 0.5 m, capsule 0.3 m,
/// walker 0.25 m), `half_height` (capsule 0.5 m; walker 0.9 m, its round
/// ends included). A walker asked for with its feet in the ground stands
/// on it.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct SpawnActor;

#[pymethods]
impl SpawnActor {
    #[new]
    #[pyo3(signature = (kind, at = None, *, rotation = None, half_extents = None, radius = None, half_height = None))]
    fn new(
        kind: &str,
        at: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
        half_extents: Option<&Bound<'_, PyAny>>,
        radius: Option<f64>,
        half_height: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let wire = spawn_command(kind, at, rotation, half_extents, radius, half_height)?;
        Ok(subclass(Self, wire))
    }

    /// `"box"`, `"sphere"`, `"capsule"`, `"vehicle"` or `"walker"`.
    #[getter]
    fn kind(slf: PyRef<'_, Self>) -> &'static str {
        match CommandKind::from_u32(slf.as_ref().wire.kind) {
            Some(CommandKind::SpawnBox) => "box",
            Some(CommandKind::SpawnSphere) => "sphere",
            Some(CommandKind::SpawnCapsule) => "capsule",
            Some(CommandKind::SpawnWalker) => "walker",
            _ => "vehicle",
        }
    }

    /// Where (x, y, z).
    #[getter]
    fn at(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
        triple(slf.as_ref().wire.vector)
    }

    /// The orientation (x, y, z, w; all zero: identity).
    #[getter]
    fn rotation(slf: PyRef<'_, Self>) -> (f32, f32, f32, f32) {
        quad(slf.as_ref().wire.rotation)
    }
}

/// Removes an actor (CARLA's `DestroyActor`).
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct DestroyActor;

#[pymethods]
impl DestroyActor {
    #[new]
    fn new(actor_id: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
        let wire = Wire::destroy(self::actor_id(actor_id)?);
        Ok(subclass(Self, wire))
    }
}

/// Teleports an actor to `position` with orientation `rotation` (a
/// quaternion x, y, z, w).
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct SetTransform;

#[pymethods]
impl SetTransform {
    #[new]
    #[pyo3(signature = (actor_id, position, rotation = None))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        position: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let rotation = rotation.map_or(Ok([0.0, 0.0, 0.0, 1.0]), |r| numbers("rotation", r))?;
        let wire = Wire::set_transform(
            self::actor_id(actor_id)?,
            numbers("position", position)?,
            rotation,
        );
        Ok(subclass(Self, wire))
    }

    /// The new position (x, y, z).
    #[getter]
    fn position(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
        triple(slf.as_ref().wire.vector)
    }

    /// The new orientation (x, y, z, w).
    #[getter]
    fn rotation(slf: PyRef<'_, Self>) -> (f32, f32, f32, f32) {
        quad(slf.as_ref().wire.rotation)
    }
}

/// Sets an actor's linear velocity (m/s) and angular velocity (rad/s).
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct SetTargetVelocity;

#[pymethods]
impl SetTargetVelocity {
    #[new]
    #[pyo3(signature = (actor_id, velocity, angular_velocity = None))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        velocity: &Bound<'_, PyAny>,
        angular_velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let angular = angular_velocity.map_or(Ok([0.0; 3]), |a| numbers("angular_velocity", a))?;
        let wire = Wire::set_target_velocity(
            self::actor_id(actor_id)?,
            numbers("velocity", velocity)?,
            angular,
        );
        Ok(subclass(Self, wire))
    }

    /// The linear velocity (m/s).
    #[getter]
    fn velocity(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
        triple(slf.as_ref().wire.vector)
    }

    /// The angular velocity (rad/s).
    #[getter]
    fn angular_velocity(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
        let r = slf.as_ref().wire.rotation;
        (r[0], r[1], r[2])
    }
}

/// A command of an actor and one vector (force, impulse, torque).
macro_rules! vector_command {
    ($(#[$doc:meta])* $name:ident, $field:ident, $build:path) => {
        $(#[$doc])*
        #[pyclass(module = "simbus", extends = Command, frozen)]
        #[derive(Debug)]
        pub(crate) struct $name;

        #[pymethods]
        impl $name {
            #[new]
            fn new(actor_id: &Bound<'_, PyAny>, $field: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
                let wire = $build(self::actor_id(actor_id)?, numbers(stringify!($field), $field)?);
                Ok(subclass(Self, wire))
            }

            #[doc = concat!("The ", stringify!($field), " (x, y, z).")]
            #[getter]
            fn $field(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
                triple(slf.as_ref().wire.vector)
            }
        }
    };
}

vector_command!(
    /// Pushes an actor with `force` newtons during the next frame.
    ApplyForce, force, Wire::apply_force
);
vector_command!(
    /// Kicks an actor with an impulse of `impulse` N·s, at once.
    ApplyImpulse, impulse, Wire::apply_impulse
);
vector_command!(
    /// Twists an actor with `torque` N·m during the next frame.
    ApplyTorque, torque, Wire::apply_torque
);

/// A command of an actor and a switch (physics, gravity).
macro_rules! switch_command {
    ($(#[$doc:meta])* $name:ident, $build:path) => {
        $(#[$doc])*
        #[pyclass(module = "simbus", extends = Command, frozen)]
        #[derive(Debug)]
        pub(crate) struct $name;

        #[pymethods]
        impl $name {
            #[new]
            #[pyo3(signature = (actor_id, enabled = true))]
            fn new(actor_id: &Bound<'_, PyAny>, enabled: bool) -> PyResult<PyClassInitializer<Self>> {
                let wire = $build(self::actor_id(actor_id)?, enabled);
                Ok(subclass(Self, wire))
            }

            /// Switched on (`True`) or off.
            #[getter]
            fn enabled(slf: PyRef<'_, Self>) -> bool {
                flag(&slf.as_ref().wire)
            }
        }
    };
}

switch_command!(
    /// Switches an actor's physics simulation on or off.
    SetSimulatePhysics, Wire::set_physics
);
switch_command!(
    /// Switches gravity on an actor on or off.
    SetEnableGravity, Wire::set_gravity
);

/// Adds the command classes to the extension module.
pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Command>()?;
    m.add_class::<SpawnActor>()?;
    m.add_class::<DestroyActor>()?;
    m.add_class::<SetTransform>()?;
    m.add_class::<SetTargetVelocity>()?;
    m.add_class::<ApplyForce>()?;
    m.add_class::<ApplyImpulse>()?;
    m.add_class::<ApplyTorque>()?;
    m.add_class::<SetSimulatePhysics>()?;
    m.add_class::<SetEnableGravity>()?;
    Ok(())
}
