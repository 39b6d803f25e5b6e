//! One full ACO control tick (rotor model, both LMS, a position-loop tick every 5th call, attitude,
//! rate, distributor) at the nominal 500/100 Hz, on a slowly varying hover-like input.

use std::hint::black_box;

use autopilot::core::control::{ControlInput, ControllerConfig, ControllerKind, Reference, new_controller};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;

fn bench_aco_tick(c: &mut Criterion) {
    let mut ctrl = new_controller(ControllerKind::ACO, &ControllerConfig::default());
    let reference = Reference::position(Vector3::new(1.0, -1.0, -3.0), 0.2);
    let mut k: u64 = 0;
    c.bench_function("aco_control_tick", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let t = (k % 5000) as f64 * 0.002;
            let input = ControlInput {
                pos_ned_m: Vector3::new(0.1 * t.sin(), -0.05 * t.cos(), -2.9),
                vel_ned_mps: Vector3::new(0.1, -0.05, 0.02 * t.sin()),
                euler_rad: Vector3::new(0.02 * t.sin(), -0.03 * t.cos(), 0.1),
                rate_frd_radps: Vector3::new(0.01, -0.02, 0.005 * t.sin()),
                specific_force_frd_mps2: Vector3::new(0.05, -0.02, -9.81 + 0.1 * t.cos()),
            };
            black_box(ctrl.update(black_box(&input), black_box(&reference)))
        });
    });
}

criterion_group!(benches, bench_aco_tick);
criterion_main!(benches);
