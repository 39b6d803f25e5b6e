//! One vehicle step as the plant link runs it at 500 Hz, without any I/O: the fused estimator (IMU
//! predict, mag, baro, GPS at 10 Hz), the commander, the telemetry due that step encoded as MAVLink 2
//! frames, and the HIL_ACTUATOR_CONTROLS reply. Disarmed on the ground, at rest: the load of a vehicle
//! waiting for a ground station (the controller, 0.24 µs a tick, comes on top when flying). The
//! two-process lockstep step costs this plus the plant's step and the UDP round trip.

use std::hint::black_box;

use autopilot::core::battery::BatterySample;
use autopilot::core::estimator::{BaroSample, GpsSample, ImuSample, MagSample};
use autopilot::core::mavlink::{MavHeader, common::MavMessage};
use autopilot::core::plant_link::{ActuatorCommand, encode_actuator_controls, encode_frame_v2};
use autopilot::core::vehicle::{Vehicle, VehicleConfig, VehicleInputs};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;

const DT_US: u64 = 2_000;

fn inputs(time_us: u64) -> VehicleInputs {
    let k = time_us / DT_US;
    let wobble = (k % 7) as f64 * 1e-3;
    VehicleInputs {
        imu: Some(ImuSample {
            time_us,
            accel_frd_mps2: Vector3::new(wobble, -wobble, -9.806_65 + wobble),
            gyro_frd_radps: Vector3::new(1e-4 * wobble, 0.0, -1e-4),
        }),
        mag: Some(MagSample { field_frd_gauss: Vector3::new(0.21, 0.012, 0.43) }),
        baro: Some(BaroSample { pressure_alt_m: 488.0 + wobble }),
        gps: time_us.is_multiple_of(100_000).then_some(GpsSample {
            time_us,
            lat_deg: 47.397_742,
            lon_deg: 8.545_594,
            alt_amsl_m: 488.0,
            vel_ned_mps: Vector3::zeros(),
            fix_type: 3,
            satellites: 12,
            eph_m: 0.5,
            epv_m: 0.8,
        }),
        truth: None,
        battery: time_us.is_multiple_of(100_000).then_some(BatterySample {
            voltage_v: 22.8,
            current_a: Some(30.0),
            remaining: Some(0.8),
            consumed_mah: Some(2000.0),
            consumed_j: Some(160_000.0),
            cells: 6,
        }),
        rc: None,
        plant_ack: None,
        plant_link: None,
    }
}

fn bench_vehicle_step(c: &mut Criterion) {
    let mut config = VehicleConfig::default();
    config.commander.disarm_preflight_s = -1.0;
    let mut vehicle = Vehicle::new(config).expect("default config");
    let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
    let mut t_us = 0;
    // Past alignment and GPS convergence, so the filter runs its full update.
    for _ in 0..5_000 {
        vehicle.step(t_us, &inputs(t_us));
        t_us += DT_US;
    }
    c.bench_function("vehicle_step_500hz_fused_on_ground", |b| {
        b.iter(|| {
            let out = vehicle.step(t_us, black_box(&inputs(t_us)));
            let mut bytes = 0;
            for m in &out.messages {
                bytes += encode_frame_v2(header, m).len();
            }
            let cmd =
                ActuatorCommand { time_us: t_us, pwm_us: out.pwm_us, armed: out.armed, motor_test: out.motor_test };
            let reply = MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd));
            bytes += encode_frame_v2(header, &reply).len();
            t_us += DT_US;
            black_box(bytes)
        });
    });
}

criterion_group!(benches, bench_vehicle_step);
criterion_main!(benches);
