//! The plant link's health as a ground station sees it, flown in lockstep with the real plant at 500 Hz
//! (the rig's hover: fused estimator, ACO, 2.5 m in Hold) with the link's faults as the plant applies them
//! (`SIM_LINK_LOSS`, `SIM_LINK_DELAY`): SYS_STATUS `drop_rate_comm` (the samples missing over the last
//! second, centi-percent) against the samples the plant's link lost over the same second, and the
//! vehicle's texts. Pure simulated time: no sleeps.

use autopilot::core::mavlink::common::{MavMessage, MavSeverity};
use autopilot::core::plant_link::health::COMPLETE_TEXT;
use tests::rig::Rig;

/// The samples of one second at 500 Hz: a lost one is 10000 / 500 = 20 centi-percent.
const SAMPLES_PER_S: u64 = 500;

/// The SYS_STATUS `drop_rate_comm` readings with their vehicle time.
fn drop_rates(messages: &[(u64, MavMessage)]) -> Vec<(u64, u16)> {
    messages
        .iter()
        .filter_map(|(t, m)| match m {
            MavMessage::SYS_STATUS(s) => Some((*t, s.drop_rate_comm)),
            _ => None,
        })
        .collect()
}

/// The plant link's texts (those starting "Plant link") with their vehicle time and severity.
fn link_texts(messages: &[(u64, MavMessage)]) -> Vec<(u64, MavSeverity, String)> {
    messages
        .iter()
        .filter_map(|(t, m)| match m {
            MavMessage::STATUSTEXT(s) => Some((*t, s.severity, s.text.to_str().unwrap_or_default().to_owned())),
            _ => None,
        })
        .filter(|(_, _, text)| text.starts_with("Plant link"))
        .collect()
}

/// What the plant's own count says `drop_rate_comm` must read at `t_us`: its samples lost in the second
/// of plant time up to `t_us`, in centi-percent of that second's samples.
fn plant_drop_rate_cpct(lost_us: &[u64], t_us: u64) -> u16 {
    let lost = lost_us.iter().filter(|&&l| l <= t_us && l + 1_000_000 > t_us).count() as u64;
    u16::try_from(lost * 10_000 / SAMPLES_PER_S).expect("at most 10000")
}

#[test]
fn given_20_percent_link_loss_in_a_hover_then_drop_rate_comm_reads_the_plants_losses_and_a_warning_then_an_info_are_said()
 {
    let mut rig = Rig::hovering();
    // WHEN the link loses 20 % of the sensor samples for 10 s.
    let loss_from_us = rig.now_us;
    rig.sim_set("SIM_LINK_LOSS", 20.0);
    rig.run_s(10.0, |_| {});
    let lossy = rig.take_messages();
    // THEN every SYS_STATUS reads exactly the plant's losses over the second before it.
    let rates = drop_rates(&lossy);
    assert!(rates.len() >= 9, "{rates:?}");
    for &(t, rate) in &rates {
        assert_eq!(rate, plant_drop_rate_cpct(&rig.link_lost_us, t), "at {t} µs");
    }
    // And, once a whole second of loss is in the window, about 2000: the second's losses are binomial (500
    // draws of 20 %: 100 +- 8.9 samples, 2000 +- 179 centi-percent); 4 sigma each, and the mean of the
    // independent seconds within 3 sigma of it (179 / sqrt(n)).
    let full: Vec<u16> = rates.iter().filter(|(t, _)| *t >= loss_from_us + 1_000_000).map(|(_, r)| *r).collect();
    let mean = full.iter().map(|&r| f64::from(r)).sum::<f64>() / full.len() as f64;
    let sigma_mean = 179.0 / (full.len() as f64).sqrt();
    println!(
        "20 % loss: drop_rate_comm {full:?} (mean {mean:.0}, {} samples lost by the plant in 10 s)",
        rig.link_lost_us.len()
    );
    assert!(full.iter().all(|&r| (1284..=2716).contains(&r)), "{full:?}");
    assert!((mean - 2000.0).abs() <= 3.0 * sigma_mean, "mean {mean:.0} of {full:?}");
    // WHEN the loss clears, and 3 s pass.
    let last_lost_us = *rig.link_lost_us.last().expect("samples were lost");
    let clear_from_us = rig.now_us;
    rig.sim_set("SIM_LINK_LOSS", 0.0);
    rig.run_s(3.0, |_| {});
    let clear = rig.take_messages();
    // THEN a WARNING within 1 s of the loss starting, with the counts of the last second; WARNINGs at most
    // once per 5 s while samples go missing (none after the loss ended, though the last second still
    // holds it); and one INFO exactly one second of samples after the last one lost, the last text.
    let said: Vec<_> = link_texts(&lossy).into_iter().chain(link_texts(&clear)).collect();
    println!(
        "texts (the loss from {loss_from_us} µs, its first samples lost at {:?} µs, its last at {last_lost_us} µs): \
         {said:?}",
        &rig.link_lost_us[..4]
    );
    let (first_us, severity, text) = said.first().cloned().expect("a warning");
    assert_eq!(severity, MavSeverity::MAV_SEVERITY_WARNING);
    assert!(first_us - loss_from_us <= 1_000_000, "said {} µs after the loss began", first_us - loss_from_us);
    assert!(text.starts_with("Plant link: ") && text.ends_with(" of 500 samples missing"), "{text}");
    let (info, warnings) = said.split_last().expect("texts");
    assert_eq!(*info, (last_lost_us + 1_000_000, MavSeverity::MAV_SEVERITY_INFO, COMPLETE_TEXT.to_owned()));
    assert!(warnings.iter().all(|(_, s, _)| *s == MavSeverity::MAV_SEVERITY_WARNING), "{said:?}");
    assert!(warnings.windows(2).all(|w| w[1].0 - w[0].0 >= 5_000_000), "{said:?}");
    assert!(warnings.len() >= 2, "10 s of loss: at least at 0 and 5 s: {said:?}");
    // (A loss just before the clear is found by the first sample after it.)
    assert!(warnings.iter().all(|w| w.0 <= clear_from_us + 2_000), "{said:?}");
    // And drop_rate_comm back to 0.
    let rates = drop_rates(&clear);
    assert!(rates.iter().all(|&(t, r)| r == plant_drop_rate_cpct(&rig.link_lost_us, t)), "{rates:?}");
    assert_eq!(rates.last().map(|r| r.1), Some(0));
    let status = rig.vehicle.plant_link_status();
    assert_eq!(status.missing_samples, rig.link_lost_us.len() as u64, "every loss counted: {status:?}");
    assert_eq!(status.late_samples, 0);
}

#[test]
fn given_no_link_loss_in_a_hover_then_drop_rate_comm_is_0_and_nothing_is_said() {
    let mut rig = Rig::hovering();
    rig.run_s(10.0, |_| {});
    let messages = rig.take_messages();
    let rates = drop_rates(&messages);
    println!("no loss: {} SYS_STATUS, drop_rate_comm {:?}", rates.len(), rates.iter().map(|r| r.1).collect::<Vec<_>>());
    assert!(rates.len() >= 9 && rates.iter().all(|&(_, r)| r == 0), "{rates:?}");
    assert_eq!(link_texts(&messages), []);
    let status = rig.vehicle.plant_link_status();
    assert_eq!((status.missing_samples, status.late_samples), (0, 0), "{status:?}");
    assert!(rig.link_lost_us.is_empty());
}

#[test]
fn given_a_link_delay_then_no_sample_is_missing_and_when_it_falls_the_overtaken_ones_are_as_the_plant_counts() {
    let mut rig = Rig::hovering();
    // WHEN the link's delay rises to 20 ms: the vehicle's clock stalls 20 ms, then runs on, nothing lost.
    rig.sim_set("SIM_LINK_DELAY", 20.0);
    rig.run_s(3.0, |_| {});
    let delayed = rig.take_messages();
    let lag_us = rig.plant.truth().time_us - rig.now_us;
    assert_eq!(rig.vehicle.plant_link_status().missing_samples, 0);
    assert!(drop_rates(&delayed).iter().all(|&(_, r)| r == 0));
    assert_eq!(link_texts(&delayed), []);
    // WHEN it falls to 0: the samples on their way are overtaken by the newest, dropped by the link and
    // missing to the vehicle.
    rig.sim_set("SIM_LINK_DELAY", 0.0);
    rig.run_s(3.0, |_| {});
    let fallen = rig.take_messages();
    let status = rig.vehicle.plant_link_status();
    println!("20 ms delay: vehicle {lag_us} µs behind the plant; when it fell {status:?}; {:?}", link_texts(&fallen));
    assert_eq!(status.missing_samples, rig.link_lost_us.len() as u64);
    assert_eq!(status.missing_samples, 10, "the 10 samples in flight behind the newest: {status:?}");
    let said = link_texts(&fallen);
    assert_eq!(
        said.iter().map(|(_, s, _)| *s).collect::<Vec<_>>(),
        [MavSeverity::MAV_SEVERITY_WARNING, MavSeverity::MAV_SEVERITY_INFO]
    );
}
