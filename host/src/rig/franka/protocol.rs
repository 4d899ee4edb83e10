//! The subset of the Franka Control Interface (FCI) research interface the driver speaks,
//! byte for byte: `#pragma pack(1)` little-endian structs of libfranka-common
//! (`include/research_interface/robot/service_types.h` and `rbk_types.h`, commit e6aa0fc,
//! 2022-02-17, protocol version [`VERSION`] = 5, as used by libfranka 0.9).
//!
//! TCP (port [`COMMAND_PORT`]): each message is a `CommandHeader { command: u32,
//! command_id: u32, size: u32 }` (size counts the header) and the command's request or
//! response. The driver sends `Connect` and `Move`. UDP: the robot sends a `RobotState` to
//! the port given in `Connect` every millisecond; the client answers each with a
//! `RobotCommand` carrying the state's `message_id`.

/// `research_interface::robot::kVersion`.
pub const VERSION: u16 = 5;
/// `kCommandPort`.
pub const COMMAND_PORT: u16 = 1337;
/// Bytes of a `CommandHeader`.
pub const HEADER_LEN: usize = 12;

/// `enum class Command : uint32_t` (first entries).
pub const CMD_CONNECT: u32 = 0;
/// `Command::kMove`.
pub const CMD_MOVE: u32 = 1;

/// `Connect::Status::kSuccess`.
pub const CONNECT_SUCCESS: u8 = 0;
/// `Connect::Status::kIncompatibleLibraryVersion`.
pub const CONNECT_INCOMPATIBLE: u8 = 1;

/// `Move::ControllerMode::kJointImpedance` (libfranka's default for Cartesian motion).
pub const CONTROLLER_JOINT_IMPEDANCE: u32 = 0;
/// `Move::MotionGeneratorMode::kCartesianPosition`.
pub const MOTION_CARTESIAN_POSITION: u32 = 2;
/// `Move::Status`, in order.
pub const MOVE_STATUS: [&str; 10] = [
    "success",
    "motion started",
    "preempted",
    "command not possible (rejected)",
    "start at singular pose (rejected)",
    "invalid argument (rejected)",
    "reflex (aborted)",
    "emergency stop (aborted)",
    "input error (aborted)",
    "aborted",
];
/// `Move::Status::kSuccess`.
pub const MOVE_SUCCESS: u8 = 0;
/// `Move::Status::kMotionStarted`.
pub const MOVE_STARTED: u8 = 1;
/// libfranka's default `Move::Deviation` for Cartesian motion (translation m, rotation
/// rad, elbow rad): the robot's own path checks are left to its defaults.
pub const DEFAULT_DEVIATION: [f64; 3] = [10.0, 3.12, 2.0 * core::f64::consts::PI];

/// `RobotMode` (rbk_types.h), in order.
pub const ROBOT_MODES: [&str; 7] = [
    "other",
    "idle",
    "move",
    "guiding",
    "reflex",
    "user stopped",
    "automatic error recovery",
];
/// `RobotMode::kIdle`.
pub const MODE_IDLE: u8 = 1;
/// `RobotMode::kMove`.
pub const MODE_MOVE: u8 = 2;

/// `RobotState`'s double arrays in declaration order, from `O_T_EE` to `dtheta` (the
/// names are in [`STATE_ARRAY_NAMES`]).
pub const STATE_ARRAYS: [usize; 39] = [
    16, 16, 16, 16, 16, 16, 1, 9, 3, 1, 9, 3, 2, 2, 7, 7, 7, 7, 7, 7, 7, 7, 7, 6, 7, 6, 7, 6, 6, 6,
    3, 2, 2, 2, 16, 6, 6, 7, 7,
];
/// The names of [`STATE_ARRAYS`], for the layout test against the header.
pub const STATE_ARRAY_NAMES: [&str; 39] = [
    "O_T_EE",
    "O_T_EE_d",
    "F_T_EE",
    "EE_T_K",
    "F_T_NE",
    "NE_T_EE",
    "m_ee",
    "I_ee",
    "F_x_Cee",
    "m_load",
    "I_load",
    "F_x_Cload",
    "elbow",
    "elbow_d",
    "tau_J",
    "tau_J_d",
    "dtau_J",
    "q",
    "q_d",
    "dq",
    "dq_d",
    "ddq_d",
    "joint_contact",
    "cartesian_contact",
    "joint_collision",
    "cartesian_collision",
    "tau_ext_hat_filtered",
    "O_F_ext_hat_K",
    "K_F_ext_hat_K",
    "O_dP_EE_d",
    "O_ddP_O",
    "elbow_c",
    "delbow_c",
    "ddelbow_c",
    "O_T_EE_c",
    "O_dP_EE_c",
    "O_ddP_EE_c",
    "theta",
    "dtheta",
];

/// Byte offset of double array `index` of [`STATE_ARRAYS`] (after the `u64 message_id`).
const fn state_array_offset(index: usize) -> usize {
    let mut doubles = 0;
    let mut i = 0;
    while i < index {
        doubles += STATE_ARRAYS[i];
        i += 1;
    }
    8 + 8 * doubles
}

/// Offset of `O_T_EE` (measured pose, column-major 4x4).
pub const STATE_O_T_EE: usize = state_array_offset(0);
/// Offset of `F_T_EE` (end effector in the flange frame, column-major 4x4).
pub const STATE_F_T_EE: usize = state_array_offset(2);
/// Offset of `q` (measured joint positions, rad).
pub const STATE_Q: usize = state_array_offset(17);
/// Offset of `O_T_EE_c` (last commanded pose, column-major 4x4).
pub const STATE_O_T_EE_C: usize = state_array_offset(34);
/// Offset of `motion_generator_mode: u8`, after the last double array.
pub const STATE_MOTION_MODE: usize = state_array_offset(STATE_ARRAYS.len());
/// Offset of `errors: [bool; 41]` (after `controller_mode: u8`).
pub const STATE_ERRORS: usize = STATE_MOTION_MODE + 2;
/// Entries of `errors` and `reflex_reason`.
pub const ERROR_COUNT: usize = 41;
/// Offset of `robot_mode: u8` (after `reflex_reason`).
pub const STATE_ROBOT_MODE: usize = STATE_ERRORS + 2 * ERROR_COUNT;
/// Bytes of a `RobotState` (ends with `control_command_success_rate: f64`).
pub const STATE_LEN: usize = STATE_ROBOT_MODE + 1 + 8;

/// Offset of `RobotCommand.motion.O_T_EE_c` (after `message_id`, `q_c`, `dq_c`).
pub const COMMAND_O_T_EE_C: usize = 8 + 8 * (7 + 7);
/// Offset of `motion.motion_generation_finished` (after `O_dP_EE_c`, `elbow_c`,
/// `valid_elbow`).
pub const COMMAND_FINISHED: usize = COMMAND_O_T_EE_C + 8 * (16 + 6 + 2) + 1;
/// Bytes of a `RobotCommand` (ends with `control.tau_J_d: [f64; 7]`).
pub const COMMAND_LEN: usize = COMMAND_FINISHED + 1 + 8 * 7;

/// A TCP message: header and payload.
#[must_use]
pub fn message(command: u32, command_id: u32, payload: &[u8]) -> Vec<u8> {
    let size = u32::try_from(HEADER_LEN + payload.len()).unwrap_or(u32::MAX);
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    for v in [command, command_id, size] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(payload);
    out
}

/// A parsed `CommandHeader`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// `Command`.
    pub command: u32,
    /// The request's id, echoed in its response.
    pub command_id: u32,
    /// Bytes of the whole message, header included.
    pub size: u32,
}

impl Header {
    /// Parses the 12 header bytes.
    #[must_use]
    pub fn parse(b: &[u8; HEADER_LEN]) -> Self {
        let u = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Self {
            command: u(0),
            command_id: u(4),
            size: u(8),
        }
    }
}

/// `Connect::Request { version: u16, udp_port: u16 }`.
#[must_use]
pub fn connect_request(udp_port: u16) -> Vec<u8> {
    let mut p = VERSION.to_le_bytes().to_vec();
    p.extend_from_slice(&udp_port.to_le_bytes());
    p
}

/// `Move::Request` for a Cartesian pose motion under joint impedance.
#[must_use]
pub fn move_request() -> Vec<u8> {
    let mut p = CONTROLLER_JOINT_IMPEDANCE.to_le_bytes().to_vec();
    p.extend_from_slice(&MOTION_CARTESIAN_POSITION.to_le_bytes());
    for d in DEFAULT_DEVIATION.iter().chain(&DEFAULT_DEVIATION) {
        p.extend_from_slice(&d.to_le_bytes());
    }
    p
}

/// Reads `n` little-endian doubles at `offset`.
fn doubles<const N: usize>(b: &[u8], offset: usize) -> [f64; N] {
    core::array::from_fn(|i| {
        let at = offset + 8 * i;
        let mut raw = [0u8; 8];
        raw.copy_from_slice(&b[at..at + 8]);
        f64::from_le_bytes(raw)
    })
}

/// The fields of a `RobotState` the driver reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Echoed in the command that answers this state.
    pub message_id: u64,
    /// Measured end-effector pose, column-major.
    pub o_t_ee: [f64; 16],
    /// The end effector in the flange frame (as set in Desk), column-major.
    pub f_t_ee: [f64; 16],
    /// Measured joint positions, rad.
    pub q_rad: [f64; 7],
    /// Last commanded end-effector pose, column-major: where a motion starts.
    pub o_t_ee_c: [f64; 16],
    /// Which of libfranka's 41 errors are active.
    pub errors: [bool; ERROR_COUNT],
    /// `RobotMode`.
    pub robot_mode: u8,
}

impl State {
    /// Parses a UDP datagram; `None` unless it is exactly [`STATE_LEN`] bytes.
    #[must_use]
    pub fn parse(b: &[u8]) -> Option<Self> {
        if b.len() != STATE_LEN {
            return None;
        }
        let mut id = [0u8; 8];
        id.copy_from_slice(&b[..8]);
        Some(Self {
            message_id: u64::from_le_bytes(id),
            o_t_ee: doubles(b, STATE_O_T_EE),
            f_t_ee: doubles(b, STATE_F_T_EE),
            q_rad: doubles(b, STATE_Q),
            o_t_ee_c: doubles(b, STATE_O_T_EE_C),
            errors: core::array::from_fn(|i| b[STATE_ERRORS + i] != 0),
            robot_mode: b[STATE_ROBOT_MODE],
        })
    }

    /// Writes these fields into a zeroed `RobotState` (the mock robot in tests).
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = vec![0u8; STATE_LEN];
        b[..8].copy_from_slice(&self.message_id.to_le_bytes());
        for (offset, m) in [
            (STATE_O_T_EE, &self.o_t_ee[..]),
            (STATE_F_T_EE, &self.f_t_ee[..]),
            (STATE_Q, &self.q_rad[..]),
            (STATE_O_T_EE_C, &self.o_t_ee_c[..]),
        ] {
            for (i, v) in m.iter().enumerate() {
                b[offset + 8 * i..offset + 8 * i + 8].copy_from_slice(&v.to_le_bytes());
            }
        }
        for (i, &e) in self.errors.iter().enumerate() {
            b[STATE_ERRORS + i] = u8::from(e);
        }
        b[STATE_ROBOT_MODE] = self.robot_mode;
        b
    }

    /// The robot mode's name.
    #[must_use]
    pub fn mode_name(&self) -> &'static str {
        ROBOT_MODES
            .get(usize::from(self.robot_mode))
            .copied()
            .unwrap_or("unknown")
    }
}

/// A `RobotCommand` for the Cartesian pose interface: `O_T_EE_c` (column-major) and
/// whether this is the motion's last sample; everything else zero.
#[must_use]
pub fn command(message_id: u64, o_t_ee_c: &[f64; 16], finished: bool) -> Vec<u8> {
    let mut b = vec![0u8; COMMAND_LEN];
    b[..8].copy_from_slice(&message_id.to_le_bytes());
    for (i, v) in o_t_ee_c.iter().enumerate() {
        let at = COMMAND_O_T_EE_C + 8 * i;
        b[at..at + 8].copy_from_slice(&v.to_le_bytes());
    }
    b[COMMAND_FINISHED] = u8::from(finished);
    b
}

/// A parsed `RobotCommand` (the mock robot in tests): message id, `O_T_EE_c`, finished.
#[must_use]
pub fn parse_command(b: &[u8]) -> Option<(u64, [f64; 16], bool)> {
    if b.len() != COMMAND_LEN {
        return None;
    }
    let mut id = [0u8; 8];
    id.copy_from_slice(&b[..8]);
    Some((
        u64::from_le_bytes(id),
        doubles(b, COMMAND_O_T_EE_C),
        b[COMMAND_FINISHED] != 0,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_match_the_packed_structs_of_rbk_types_h() {
        // Sums written out from the header, independently of the table above.
        assert_eq!(STATE_ARRAY_NAMES[34], "O_T_EE_c");
        assert_eq!(STATE_O_T_EE, 8);
        assert_eq!(
            (STATE_ARRAY_NAMES[2], STATE_F_T_EE),
            ("F_T_EE", 8 + 8 * 2 * 16)
        );
        // O_T_EE .. NE_T_EE; m_ee .. F_x_Cload; elbow, elbow_d; tau_J, tau_J_d, dtau_J.
        let before_q = 6 * 16 + (1 + 9 + 3) * 2 + 2 * 2 + 3 * 7;
        assert_eq!((STATE_ARRAY_NAMES[17], STATE_Q), ("q", 8 + 8 * before_q));
        // O_T_EE .. NE_T_EE; m_ee, I_ee, F_x_Cee, m_load, I_load, F_x_Cload; elbow,
        // elbow_d; tau_J .. joint_contact (nine 7-arrays); cartesian_contact,
        // joint_collision, cartesian_collision; tau_ext_hat_filtered; O_F_ext_hat_K,
        // K_F_ext_hat_K, O_dP_EE_d; O_ddP_O; elbow_c, delbow_c, ddelbow_c.
        let before_o_t_ee_c =
            6 * 16 + (1 + 9 + 3) * 2 + 2 * 2 + 9 * 7 + (6 + 7 + 6) + 7 + 3 * 6 + 3 + 3 * 2;
        assert_eq!(before_o_t_ee_c, 242);
        assert_eq!(STATE_O_T_EE_C, 8 + 8 * before_o_t_ee_c);
        assert_eq!(STATE_MOTION_MODE, 8 + 8 * 284);
        assert_eq!(STATE_LEN, 2373);
        assert_eq!(COMMAND_LEN, 8 + 8 * 38 + 2 + 8 * 7);
        assert_eq!(message(CMD_CONNECT, 7, &connect_request(4000)).len(), 16);
        assert_eq!(
            message(CMD_MOVE, 8, &move_request()).len(),
            12 + 4 + 4 + 6 * 8
        );
    }

    #[test]
    fn states_and_commands_round_trip() {
        let mut errors = [false; ERROR_COUNT];
        errors[40] = true;
        let s = State {
            message_id: 9,
            o_t_ee: core::array::from_fn(|i| i as f64),
            f_t_ee: core::array::from_fn(|i| 100.0 + i as f64),
            q_rad: core::array::from_fn(|i| 0.1 * i as f64),
            o_t_ee_c: core::array::from_fn(|i| -(i as f64)),
            errors,
            robot_mode: 4,
        };
        assert_eq!(State::parse(&s.encode()), Some(s));
        assert_eq!(s.mode_name(), "reflex");
        let m = core::array::from_fn(|i| 0.5 * i as f64);
        assert_eq!(parse_command(&command(3, &m, true)), Some((3, m, true)));
        assert!(State::parse(&[0; 10]).is_none());
    }
}
