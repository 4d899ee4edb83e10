//! The Franka driver against a mock robot on loopback that speaks the FCI subset it uses
//! (TCP `Connect` and `Move`, UDP `RobotState` / `RobotCommand`, riseg's
//! `rig::franka::protocol`) and records every commanded pose: the path, its limits, the
//! refusal before anything is sent of a push out of the workspace, past the Panda's joint
//! limits or out of its reach, and clear errors on a lost connection, a reflex mid-push, a
//! robot already in error and another protocol version. The mock reports the joint
//! positions, `F_T_EE` and pose of a Panda with a Franka Hand at its ready pose.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use core::{
    f64::consts::{FRAC_1_SQRT_2, FRAC_PI_2, FRAC_PI_4},
    time::Duration,
};
use std::{
    io::{ErrorKind, Read, Write},
    net::{TcpListener, UdpSocket},
    thread::JoinHandle,
    time::Instant,
};

use nalgebra::{Point3, Vector3};
use riseg::rig::{
    franka::{
        Franka, FrankaConfig,
        protocol::{self, ERROR_COUNT, State},
        trajectory::{DT_S, FRANKA_MAX_VEL_M_PER_S, MotionLimits},
    },
    robot::{PushCommand, PushLimits, Robot},
};

#[derive(Clone, Copy, PartialEq)]
enum Fault {
    None,
    /// Stops answering after this many commands of a motion.
    LoseAfter(usize),
    /// A reflex after this many commands.
    ReflexAfter(usize),
    /// In reflex from the start.
    ErrorAtStart,
    /// Speaks protocol version 9.
    Incompatible,
}

/// What the mock saw.
#[derive(Debug, Default)]
struct Seen {
    moves: usize,
    poses: Vec<[f64; 16]>,
    finished: Vec<usize>,
}

/// The robot's idle joint positions: Franka's ready pose.
const READY_RAD: [f64; 7] = [
    0.0,
    -FRAC_PI_4,
    0.0,
    -3.0 * FRAC_PI_4,
    0.0,
    FRAC_PI_2,
    FRAC_PI_4,
];

/// `F_T_EE` of the Franka Hand (column-major): 10.34 cm along the flange's z, turned
/// -45° about it.
fn hand() -> [f64; 16] {
    let h = FRAC_1_SQRT_2;
    [
        h, -h, 0.0, 0.0, h, h, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.1034, 1.0,
    ]
}

/// The robot's idle pose `O_T_EE` (column-major) at [`READY_RAD`] with [`hand`]: tool
/// pointing down (x flipped), at (0.3069, 0, 0.4869), as a Panda reports it. Computed
/// independently of riseg (numpy on franka_description's URDF chain).
fn home() -> [f64; 16] {
    [
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        -1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        -1.0,
        0.0,
        0.3068905666,
        0.0,
        0.4868820523,
        1.0,
    ]
}

fn read_message(tcp: &mut std::net::TcpStream) -> Option<(protocol::Header, Vec<u8>)> {
    let mut head = [0u8; protocol::HEADER_LEN];
    tcp.read_exact(&mut head).ok()?;
    let h = protocol::Header::parse(&head);
    let mut payload = vec![0u8; h.size as usize - protocol::HEADER_LEN];
    tcp.read_exact(&mut payload).ok()?;
    Some((h, payload))
}

fn mock(fault: Fault) -> (u16, JoinHandle<Seen>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let handle = std::thread::spawn(move || {
        let mut seen = Seen::default();
        let (mut tcp, _) = listener.accept().unwrap();
        let (h, p) = read_message(&mut tcp).unwrap();
        assert_eq!((h.command, h.size), (protocol::CMD_CONNECT, 16));
        assert_eq!(u16::from_le_bytes([p[0], p[1]]), protocol::VERSION);
        let client = ("127.0.0.1", u16::from_le_bytes([p[2], p[3]]));
        let reply = if fault == Fault::Incompatible {
            vec![protocol::CONNECT_INCOMPATIBLE, 9, 0]
        } else {
            vec![protocol::CONNECT_SUCCESS, 5, 0]
        };
        tcp.write_all(&protocol::message(
            protocol::CMD_CONNECT,
            h.command_id,
            &reply,
        ))
        .unwrap();
        if fault == Fault::Incompatible {
            return seen;
        }
        let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
        udp.set_read_timeout(Some(Duration::from_millis(1)))
            .unwrap();
        tcp.set_nonblocking(true).unwrap();
        let mut state = State {
            message_id: 0,
            o_t_ee: home(),
            // The mock does not move its joints: every push returns home, where they are
            // right again before the next push reads them.
            f_t_ee: hand(),
            q_rad: READY_RAD,
            o_t_ee_c: home(),
            errors: [false; ERROR_COUNT],
            robot_mode: if fault == Fault::ErrorAtStart {
                4
            } else {
                protocol::MODE_IDLE
            },
        };
        if fault == Fault::ErrorAtStart {
            state.errors[7] = true;
        }
        let mut motion: Option<u32> = None;
        let mut last_id = 0;
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut buf = [0u8; 4096];
        while Instant::now() < deadline {
            // A Move request starts a motion (checked before each state, and again when a
            // command arrives first: the request may still be in flight).
            let mut poll_move =
                |motion: &mut Option<u32>, state: &mut State| match read_message_nonblocking(
                    &mut tcp,
                ) {
                    Ok(Some((h, p))) => {
                        assert_eq!((h.command, h.size, p.len()), (protocol::CMD_MOVE, 68, 56));
                        assert_eq!(
                            u32::from_le_bytes([p[4], p[5], p[6], p[7]]),
                            protocol::MOTION_CARTESIAN_POSITION
                        );
                        *motion = Some(h.command_id);
                        let started = protocol::message(
                            protocol::CMD_MOVE,
                            h.command_id,
                            &[protocol::MOVE_STARTED],
                        );
                        tcp.write_all(&started).unwrap();
                        state.robot_mode = protocol::MODE_MOVE;
                        Ok(true)
                    }
                    Ok(None) => Ok(false),
                    Err(()) => Err(()),
                };
            match poll_move(&mut motion, &mut state) {
                Ok(true) => seen.moves += 1,
                Ok(false) => {}
                Err(()) => return seen,
            }
            state.message_id += 1;
            udp.send_to(&state.encode(), client).unwrap();
            // Lockstep during a motion (a generous wait: a loaded CI machine), 1 kHz-ish idle.
            let wait_ms = if motion.is_some() { 100 } else { 1 };
            udp.set_read_timeout(Some(Duration::from_millis(wait_ms)))
                .unwrap();
            let Ok((n, _)) = udp.recv_from(&mut buf) else {
                continue;
            };
            let (id, pose, finished) = protocol::parse_command(&buf[..n]).unwrap();
            assert!(
                id > last_id && id <= state.message_id,
                "a command answers a new state: {id}"
            );
            last_id = id;
            let wait_for_move = Instant::now() + Duration::from_millis(500);
            while motion.is_none() && Instant::now() < wait_for_move {
                match poll_move(&mut motion, &mut state) {
                    Ok(true) => seen.moves += 1,
                    Ok(false) => std::thread::sleep(Duration::from_millis(1)),
                    Err(()) => return seen,
                }
            }
            let move_id = motion.expect("commands only during a motion");
            seen.poses.push(pose);
            state.o_t_ee_c = pose;
            state.o_t_ee = pose;
            let k = seen.poses.len();
            if fault == Fault::LoseAfter(k) {
                return seen;
            }
            if fault == Fault::ReflexAfter(k) {
                state.robot_mode = 4;
                state.errors[3] = true;
                let abort = protocol::message(protocol::CMD_MOVE, move_id, &[6]);
                tcp.write_all(&abort).unwrap();
            }
            if finished {
                seen.finished.push(k - 1);
                let done =
                    protocol::message(protocol::CMD_MOVE, move_id, &[protocol::MOVE_SUCCESS]);
                tcp.write_all(&done).unwrap();
                motion = None;
                state.robot_mode = protocol::MODE_IDLE;
            }
        }
        seen
    });
    (port, handle)
}

/// A whole message if one is waiting; `Err` when the client closed the connection.
fn read_message_nonblocking(
    tcp: &mut std::net::TcpStream,
) -> Result<Option<(protocol::Header, Vec<u8>)>, ()> {
    let mut probe = [0u8; 1];
    match tcp.peek(&mut probe) {
        Ok(0) => Err(()),
        Ok(_) => {
            tcp.set_nonblocking(false).unwrap();
            let m = read_message(tcp);
            tcp.set_nonblocking(true).unwrap();
            m.map(Some).ok_or(())
        }
        Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(None),
        Err(_) => Err(()),
    }
}

fn limits() -> PushLimits {
    PushLimits {
        workspace_min_m: [0.3, -0.25, 0.0],
        workspace_max_m: [0.7, 0.25, 0.3],
        max_push_len_m: 0.06,
    }
}

fn connect(port: u16) -> Franka {
    // Brisker than the default so the test streams a few thousand samples, not tens
    // (3 m/s² would already take joint 2 past its acceleration limit on the descent).
    let motion = MotionLimits {
        max_vel_m_per_s: 0.5,
        max_acc_m_per_s2: 2.0,
        max_jerk_m_per_s3: 500.0,
        hover_m: 0.1,
    };
    connect_with(port, limits(), motion)
}

fn connect_with(port: u16, limits: PushLimits, motion: MotionLimits) -> Franka {
    let mut config = FrankaConfig::new("127.0.0.1", limits);
    config.command_port = port;
    config.motion = motion;
    config.state_timeout_ms = 200;
    Franka::connect(config).unwrap()
}

fn push(x: f32) -> PushCommand {
    PushCommand {
        start_robot_m: Point3::new(x, 0.0, 0.02),
        direction_robot: Vector3::y(),
        length_m: 0.03,
    }
}

fn position(m: &[f64; 16]) -> Point3<f64> {
    Point3::new(m[12], m[13], m[14])
}

#[test]
fn a_push_hovers_descends_pushes_level_lifts_and_returns_within_the_limits() {
    let (port, server) = mock(Fault::None);
    let mut robot = connect(port);
    robot.execute(&push(0.5)).unwrap();
    drop(robot);
    let seen = server.join().unwrap();
    assert_eq!(seen.moves, 1);
    let n = seen.poses.len();
    assert!(n > 1000, "{n} samples");
    assert_eq!(
        seen.finished,
        vec![n - 1],
        "only the last sample ends the motion"
    );
    // Orientation held: every rotation part is home's.
    assert!(seen.poses.iter().all(|m| m[..12] == home()[..12]));
    let p: Vec<Point3<f64>> = seen.poses.iter().map(position).collect();
    assert!((p[n - 1] - position(&home())).norm() < 1e-9, "returns home");
    // The push: level at 2 cm from (0.5, 0) to (0.5, 0.03), approached and left from 10 cm up.
    let low: Vec<&Point3<f64>> = p.iter().filter(|q| q.z < 0.0200001).collect();
    assert!(
        low.iter()
            .all(|q| (q.x - 0.5).abs() < 1e-9 && q.y > -1e-9 && q.y < 0.03 + 1e-9)
    );
    assert!(low.iter().any(|q| q.y.abs() < 1e-9) && low.iter().any(|q| (q.y - 0.03).abs() < 1e-9));
    assert!(
        p.iter()
            .any(|q| (q - Point3::new(0.5, 0.0, 0.12)).norm() < 1e-9),
        "hover above the start"
    );
    assert!(
        p.iter()
            .any(|q| (q - Point3::new(0.5, 0.03, 0.12)).norm() < 1e-9),
        "lift above the end"
    );
    // Commanded at 1 kHz within the configured speed (below Franka's 1.7 m/s).
    const { assert!(0.5 * 1.01 < FRANKA_MAX_VEL_M_PER_S) };
    let fastest = p
        .windows(2)
        .map(|w| (w[1] - w[0]).norm() / DT_S)
        .fold(0.0, f64::max);
    assert!(fastest <= 0.5 * 1.01, "{fastest}");
    assert!(fastest > 0.4, "uses the speed it may: {fastest}");
}

#[test]
fn an_out_of_workspace_push_is_refused_before_anything_is_sent() {
    let (port, server) = mock(Fault::None);
    let mut robot = connect(port);
    let err = robot.execute(&push(0.9)).unwrap_err().to_string();
    assert!(
        err.contains("push refused") && err.contains("outside the workspace"),
        "{err}"
    );
    // Inside the box at the start, but hovering 10 cm over z = 0.25 leaves it.
    let high = PushCommand {
        start_robot_m: Point3::new(0.5, 0.0, 0.25),
        ..push(0.5)
    };
    let err = robot.execute(&high).unwrap_err().to_string();
    assert!(err.contains("outside the workspace"), "{err}");
    drop(robot);
    let seen = server.join().unwrap();
    assert_eq!((seen.moves, seen.poses.len()), (0, 0));
}

#[test]
fn a_push_past_the_panda_joint_limits_is_refused_before_any_motion_command() {
    let (port, server) = mock(Fault::None);
    // Within Franka's Cartesian limits (1.7 m/s, 13 m/s², 6500 m/s³), too hard on the joints.
    let brisk = MotionLimits {
        max_vel_m_per_s: 1.6,
        max_acc_m_per_s2: 12.0,
        max_jerk_m_per_s3: 6000.0,
        hover_m: 0.1,
    };
    let mut robot = connect_with(port, limits(), brisk);
    let err = robot.execute(&push(0.5)).unwrap_err().to_string();
    assert!(
        err.contains("push refused: joint ")
            && err.contains(" s is beyond the Panda's limit ")
            && err.contains("at t = "),
        "{err}"
    );
    drop(robot);
    let seen = server.join().unwrap();
    assert_eq!((seen.moves, seen.poses.len()), (0, 0), "nothing was sent");
}

#[test]
fn a_push_out_of_the_arm_s_reach_is_refused_before_any_motion_command() {
    let (port, server) = mock(Fault::None);
    // A workspace box drawn wider than the arm reaches (the shoulder is at 0.333 m).
    let wide = PushLimits {
        workspace_min_m: [0.3, -0.25, 0.0],
        workspace_max_m: [1.3, 0.25, 0.3],
        max_push_len_m: 0.06,
    };
    let mut robot = connect_with(port, wide, MotionLimits::default());
    let err = robot.execute(&push(1.1)).unwrap_err().to_string();
    assert!(
        err.contains("push refused: the path is not reachable"),
        "{err}"
    );
    drop(robot);
    let seen = server.join().unwrap();
    assert_eq!((seen.moves, seen.poses.len()), (0, 0), "nothing was sent");
}

#[test]
fn a_lost_connection_mid_push_is_a_clear_error() {
    let (port, server) = mock(Fault::LoseAfter(100));
    let mut robot = connect(port);
    let err = robot.execute(&push(0.5)).unwrap_err().to_string();
    assert!(
        err.contains("Franka at 127.0.0.1") && err.contains("lost connection during the push"),
        "{err}"
    );
    assert_eq!(server.join().unwrap().poses.len(), 100);
}

#[test]
fn a_reflex_mid_push_and_an_error_before_it_stop_with_the_robot_mode() {
    let (port, server) = mock(Fault::ReflexAfter(50));
    let mut robot = connect(port);
    let err = robot.execute(&push(0.5)).unwrap_err().to_string();
    assert!(
        err.contains("mode 'reflex'") && err.contains("[3]") && err.contains("during the push"),
        "{err}"
    );
    drop(robot);
    assert!(server.join().unwrap().poses.len() <= 52);

    let (port, server) = mock(Fault::ErrorAtStart);
    let mut robot = connect(port);
    let err = robot.execute(&push(0.5)).unwrap_err().to_string();
    assert!(
        err.contains("mode 'reflex'") && err.contains("[7]"),
        "{err}"
    );
    drop(robot);
    assert_eq!(
        server.join().unwrap().moves,
        0,
        "no motion is started on a robot in error"
    );
}

#[test]
fn another_protocol_version_and_no_robot_are_clear_errors() {
    let (port, server) = mock(Fault::Incompatible);
    let mut config = FrankaConfig::new("127.0.0.1", limits());
    config.command_port = port;
    let err = Franka::connect(config.clone()).unwrap_err().to_string();
    assert!(
        err.contains("protocol version 9") && err.contains("version 5"),
        "{err}"
    );
    server.join().unwrap();
    // Nothing listens there any more.
    let err = Franka::connect(config).unwrap_err().to_string();
    assert!(err.contains("connecting"), "{err}");
}
