//! Franka Emika Panda as the loop's [`Robot`] (feature `franka`): an own client of the
//! Franka Control Interface (FCI) for the one motion a push needs.
//!
//! # Contract
//!
//! - [`Franka::connect`] opens the FCI command connection (TCP, [`protocol::COMMAND_PORT`])
//!   and says `Connect` with protocol version [`protocol::VERSION`]; a robot that speaks
//!   another version is a clear error naming both. The robot then streams its state over
//!   UDP every millisecond.
//! - [`Robot::execute`] reads the current state, refuses to move if the robot is in an
//!   error or reflex state (naming the mode and the active error numbers), plans the push
//!   from the last commanded pose ([`trajectory::plan`]: hover, descend, push, lift,
//!   return, orientation held) and checks every 1 kHz sample against the workspace box and
//!   the velocity, acceleration and jerk limits ([`trajectory::check`]), then tracks the
//!   path in joint space from the measured joint positions and checks every sample for
//!   reachability and against the Panda's joint position, velocity, acceleration and jerk
//!   limits ([`kinematics::check`]), before anything is sent. Only then it sends `Move`
//!   (Cartesian pose generator, joint impedance) and answers each state with the next
//!   pose, the last one flagged as finished, and waits for the robot's `Move` result.
//! - A state that does not arrive within [`FrankaConfig::state_timeout_ms`], a closed
//!   command connection, a reflex during the motion or any `Move` result but success is a
//!   [`RobotError`] naming the robot's address and the cause; the loop stops on it. The
//!   robot itself stops a motion whose commands stop arriving (FCI's communication
//!   constraints), so a lost client never leaves the arm moving.
//!
//! Not covered: stopping a push half-way (it lasts a few seconds; the arm's stop button is
//! the immediate stop), and the robot's own inverse kinematics: the joint check follows
//! the path with its own (joint 3 held), so if the robot resolves the redundancy
//! otherwise and comes closer to a limit, the push may still end in a reflex, reported as
//! above. The robot's own settings (collision thresholds, impedance, end-effector frame and load)
//! are left as Desk configured them; set them in Desk before the first live push.

pub mod kinematics;
pub mod protocol;
pub mod trajectory;

use core::{net::SocketAddr, time::Duration};
use std::{
    io::{Read as _, Write as _},
    net::{TcpStream, ToSocketAddrs as _, UdpSocket},
};

use nalgebra::{Matrix4, Point3};

use crate::rig::robot::{PushCommand, PushLimits, Robot, RobotError};
use protocol::State;
use trajectory::MotionLimits;

/// How to reach the robot and what it may do.
#[derive(Debug, Clone, PartialEq)]
pub struct FrankaConfig {
    /// The robot's FCI address (the controller's IP or host name).
    pub host: String,
    /// The command port ([`protocol::COMMAND_PORT`] on a real robot).
    pub command_port: u16,
    /// Where pushes may go, robot base frame.
    pub limits: PushLimits,
    /// Speed, acceleration, jerk and hover height of a push.
    pub motion: MotionLimits,
    /// Longest wait for one robot state during a motion, milliseconds.
    pub state_timeout_ms: u64,
}

impl FrankaConfig {
    /// A robot at `host` with the default port, limits and gentle motion.
    #[must_use]
    pub fn new(host: &str, limits: PushLimits) -> Self {
        Self {
            host: host.to_owned(),
            command_port: protocol::COMMAND_PORT,
            limits,
            motion: MotionLimits::default(),
            state_timeout_ms: 100,
        }
    }
}

/// A connected Panda (module docs).
#[derive(Debug)]
pub struct Franka {
    config: FrankaConfig,
    address: SocketAddr,
    tcp: TcpStream,
    udp: UdpSocket,
    next_command_id: u32,
}

impl Franka {
    /// Connects to the robot (module docs).
    ///
    /// # Errors
    /// [`RobotError`] naming the address: unreachable, refused, or another protocol version.
    pub fn connect(config: FrankaConfig) -> Result<Self, RobotError> {
        config
            .motion
            .validate()
            .map_err(|e| RobotError(format!("Franka motion limits: {e}")))?;
        let name = format!("{}:{}", config.host, config.command_port);
        let fail = |what: &str, e: &dyn core::fmt::Display| {
            RobotError(format!("Franka at {name}: {what}: {e}"))
        };
        let address = (config.host.as_str(), config.command_port)
            .to_socket_addrs()
            .map_err(|e| fail("resolving the address", &e))?
            .next()
            .ok_or_else(|| fail("resolving the address", &"no address"))?;
        let tcp = TcpStream::connect_timeout(&address, Duration::from_secs(3))
            .map_err(|e| fail("connecting (is FCI enabled in Desk?)", &e))?;
        let local_ip = tcp
            .local_addr()
            .map_err(|e| fail("local address", &e))?
            .ip();
        let udp = UdpSocket::bind((local_ip, 0)).map_err(|e| fail("opening the UDP port", &e))?;
        let timeout = Duration::from_millis(config.state_timeout_ms.max(1));
        udp.set_read_timeout(Some(timeout))
            .map_err(|e| fail("UDP timeout", &e))?;
        tcp.set_read_timeout(Some(Duration::from_secs(5)))
            .map_err(|e| fail("TCP timeout", &e))?;
        let udp_port = udp.local_addr().map_err(|e| fail("UDP port", &e))?.port();
        let mut robot = Self {
            config,
            address,
            tcp,
            udp,
            next_command_id: 1,
        };
        let id = robot.send(protocol::CMD_CONNECT, &protocol::connect_request(udp_port))?;
        let payload = robot.response(protocol::CMD_CONNECT, id)?;
        match payload.as_slice() {
            [protocol::CONNECT_SUCCESS, ..] => Ok(robot),
            [protocol::CONNECT_INCOMPATIBLE, lo, hi, ..] => Err(robot.error(&format!(
                "the robot speaks FCI protocol version {}, riseg's client version {}: \
                 use a robot system version matching libfranka 0.9",
                u16::from_le_bytes([*lo, *hi]),
                protocol::VERSION
            ))),
            other => Err(robot.error(&format!("Connect refused ({other:?})"))),
        }
    }

    fn error(&self, what: &str) -> RobotError {
        RobotError(format!("Franka at {}: {what}", self.address))
    }

    /// Sends a TCP request; returns its command id.
    fn send(&mut self, command: u32, payload: &[u8]) -> Result<u32, RobotError> {
        let id = self.next_command_id;
        self.next_command_id = id.wrapping_add(1);
        self.tcp
            .write_all(&protocol::message(command, id, payload))
            .map_err(|e| self.error(&format!("lost the command connection: {e}")))?;
        Ok(id)
    }

    /// Reads the response to request `id` of `command`: its payload.
    fn response(&mut self, command: u32, id: u32) -> Result<Vec<u8>, RobotError> {
        let mut head = [0u8; protocol::HEADER_LEN];
        self.tcp
            .read_exact(&mut head)
            .map_err(|e| self.error(&format!("lost the command connection: {e}")))?;
        let h = protocol::Header::parse(&head);
        let len = (h.size as usize).saturating_sub(protocol::HEADER_LEN);
        if h.command != command || h.command_id != id || len > 1024 {
            return Err(self.error(&format!(
                "unexpected response {h:?} to command {command} id {id}"
            )));
        }
        let mut payload = vec![0u8; len];
        self.tcp
            .read_exact(&mut payload)
            .map_err(|e| self.error(&format!("lost the command connection: {e}")))?;
        Ok(payload)
    }

    /// The newest robot state from the robot's address (older queued ones are skipped, as
    /// libfranka does), and where it came from; `context` words a timeout.
    fn next_state(&self, context: &str) -> Result<(State, SocketAddr), RobotError> {
        let mut buf = vec![0u8; protocol::STATE_LEN + 1];
        let lost = |e: std::io::Error| {
            self.error(&format!(
                "lost connection{context}: no robot state within {} ms ({e})",
                self.config.state_timeout_ms
            ))
        };
        let mut newest = None;
        loop {
            let got = if newest.is_none() {
                self.udp.set_nonblocking(false).map_err(lost)?;
                self.udp.recv_from(&mut buf).map_err(lost)?
            } else {
                self.udp.set_nonblocking(true).map_err(lost)?;
                match self.udp.recv_from(&mut buf) {
                    Ok(got) => got,
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                    Err(e) => return Err(lost(e)),
                }
            };
            let (n, from) = got;
            if from.ip() != self.address.ip() {
                continue;
            }
            let state = State::parse(&buf[..n]).ok_or_else(|| {
                self.error(&format!(
                    "a state datagram of {n} bytes, not {}: another FCI protocol version?",
                    protocol::STATE_LEN
                ))
            })?;
            newest = Some((state, from));
        }
        newest.ok_or_else(|| self.error("no robot state"))
    }

    /// Refuses to go on when the robot reports an error or is not idle/moving.
    fn healthy(&self, s: &State) -> Result<(), RobotError> {
        let active: Vec<usize> = (0..protocol::ERROR_COUNT)
            .filter(|&i| s.errors[i])
            .collect();
        if !active.is_empty() || !matches!(s.robot_mode, protocol::MODE_IDLE | protocol::MODE_MOVE)
        {
            return Err(self.error(&format!(
                "robot in mode '{}' with errors {active:?} (libfranka's franka::Errors order); \
                 clear it in Desk (or automatic error recovery) before pushing",
                s.mode_name()
            )));
        }
        Ok(())
    }

    /// Streams `poses` (column-major) answering each state; then waits for `Move`'s result.
    fn stream(&mut self, poses: &[[f64; 16]], move_id: u32) -> Result<(), RobotError> {
        let Some(last) = poses.len().checked_sub(1) else {
            return Ok(());
        };
        let mut udp_to = None;
        for (i, pose) in poses.iter().enumerate() {
            let (s, from) = self.next_state(&format!(
                " during the push at sample {i} of {}",
                poses.len()
            ))?;
            self.healthy(&s)
                .map_err(|e| RobotError(format!("{} (during the push, at sample {i})", e.0)))?;
            let to = *udp_to.get_or_insert(from);
            self.udp
                .send_to(&protocol::command(s.message_id, pose, i == last), to)
                .map_err(|e| self.error(&format!("sending a command: {e}")))?;
        }
        let result = self.response(protocol::CMD_MOVE, move_id)?;
        // The robot may first confirm the start, then report the end.
        let status = if result.first() == Some(&protocol::MOVE_STARTED) {
            self.response(protocol::CMD_MOVE, move_id)?
        } else {
            result
        };
        match status.first() {
            Some(&protocol::MOVE_SUCCESS) => Ok(()),
            Some(&s) => Err(self.error(&format!(
                "the push ended with '{}'",
                protocol::MOVE_STATUS
                    .get(usize::from(s))
                    .copied()
                    .unwrap_or("unknown status")
            ))),
            None => Err(self.error("an empty Move response")),
        }
    }
}

/// A column-major 4x4 (FCI's layout) as a matrix.
fn matrix(cm: &[f64; 16]) -> Matrix4<f64> {
    Matrix4::from_column_slice(cm)
}

impl Robot for Franka {
    fn limits(&self) -> PushLimits {
        self.config.limits
    }

    fn execute(&mut self, cmd: &PushCommand) -> Result<(), RobotError> {
        self.config
            .limits
            .check(cmd)
            .map_err(|e| self.error(&format!("push refused: {e}")))?;
        let (s, _) = self.next_state("")?;
        self.healthy(&s)?;
        let start = matrix(&s.o_t_ee_c);
        let home = Point3::new(start[(0, 3)], start[(1, 3)], start[(2, 3)]);
        let traj = trajectory::plan(home, cmd, &self.config.motion)
            .map_err(|e| self.error(&format!("push refused: {e}")))?;
        trajectory::check(&traj, &self.config.limits, &self.config.motion)
            .map_err(|e| self.error(&format!("push refused: {e}")))?;
        kinematics::check(
            &s.q_rad,
            &matrix(&s.f_t_ee),
            &matrix(&s.o_t_ee),
            &traj.positions_m,
        )
        .map_err(|e| self.error(&format!("push refused: {e}")))?;
        let poses: Vec<[f64; 16]> = traj
            .positions_m
            .iter()
            .map(|p| {
                let mut m = start;
                m[(0, 3)] = p.x;
                m[(1, 3)] = p.y;
                m[(2, 3)] = p.z;
                let mut cm = [0.0; 16];
                cm.copy_from_slice(m.as_slice());
                cm
            })
            .collect();
        let id = self.send(protocol::CMD_MOVE, &protocol::move_request())?;
        self.stream(&poses, id)
    }
}
