use super::*;

const TICK: Duration = Duration::from_millis(100);

/// Candidates on a virtual network: every 100 ms each live one hears the others' leases
/// (unless the pair is cut), then ticks.
struct Net {
    now: Instant,
    cands: Vec<Election>,
    up: Vec<bool>,
    /// Candidates in different groups hear nothing of each other (a partition).
    group: Vec<u8>,
    /// A candidate hears nothing before this (a link still authenticating).
    deaf_until: Vec<Instant>,
}

impl Net {
    fn new(priorities: &[u32]) -> Net {
        let now = Instant::now();
        Net {
            now,
            cands: priorities
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    Election::new(
                        format!("c{i}"),
                        *p,
                        String::new(),
                        ElectionConfig::default(),
                        now,
                    )
                })
                .collect(),
            up: vec![true; priorities.len()],
            group: vec![0; priorities.len()],
            deaf_until: vec![now; priorities.len()],
        }
    }

    fn step(&mut self) {
        self.now += TICK;
        let leases: Vec<_> = self.cands.iter().map(|c| c.lease().clone()).collect();
        for i in 0..self.cands.len() {
            for (j, l) in leases.iter().enumerate() {
                if i != j
                    && self.up[i]
                    && self.up[j]
                    && self.group[i] == self.group[j]
                    && self.now >= self.deaf_until[i]
                {
                    self.cands[i].heard(l.clone(), self.now);
                }
            }
        }
        for i in 0..self.cands.len() {
            if self.up[i] {
                self.cands[i].tick(self.now);
            }
        }
    }

    fn run(&mut self, d: Duration) {
        let end = self.now + d;
        while self.now < end {
            self.step();
            assert!(self.actives_per_group().iter().all(|n| *n <= 1) || self.partitioned());
        }
    }

    fn partitioned(&self) -> bool {
        self.group.iter().any(|g| *g != self.group[0])
    }

    fn actives_per_group(&self) -> Vec<usize> {
        let mut n = vec![0; 4];
        for (i, c) in self.cands.iter().enumerate() {
            if self.up[i] && c.role() == CoordinatorRole::Active {
                n[usize::from(self.group[i])] += 1;
            }
        }
        n
    }

    fn actives(&self) -> Vec<usize> {
        (0..self.cands.len())
            .filter(|i| self.up[*i] && self.cands[*i].role() == CoordinatorRole::Active)
            .collect()
    }

    /// Steps until `cond` holds; the time it took.
    fn until(&mut self, max: Duration, cond: impl Fn(&Net) -> bool) -> Duration {
        let start = self.now;
        while !cond(self) {
            assert!(self.now - start < max, "not within {max:?}");
            self.step();
        }
        self.now - start
    }

    fn restart(&mut self, i: usize) {
        self.restart_with(i, ElectionConfig::default(), Duration::ZERO);
    }

    /// Candidate `i` starts again with `config`, hearing nothing for `deaf`.
    fn restart_with(&mut self, i: usize, config: ElectionConfig, deaf: Duration) {
        self.up[i] = true;
        self.deaf_until[i] = self.now + deaf;
        let l = self.cands[i].lease().clone();
        self.cands[i] = Election::new(l.coordinator_id, l.priority, l.api_url, config, self.now);
    }
}

#[test]
fn the_highest_priority_is_elected_after_listening_one_lease_timeout() {
    let mut net = Net::new(&[1, 2, 1]);
    net.run(Duration::from_millis(900));
    assert!(net.actives().is_empty(), "nobody claims before listening");
    net.run(Duration::from_millis(300));
    assert_eq!(net.actives(), vec![1]);
    assert_eq!(net.cands[1].lease().epoch, 1);
    for c in &net.cands {
        assert_eq!(c.active().map(|l| l.coordinator_id.as_str()), Some("c1"));
    }
}

#[test]
fn equal_priorities_elect_the_smaller_id_only() {
    let mut net = Net::new(&[3, 3]);
    net.run(Duration::from_secs(3));
    assert_eq!(net.actives(), vec![0]);
}

#[test]
fn the_standby_takes_over_within_two_seconds_with_the_next_epoch() {
    let mut net = Net::new(&[2, 1]);
    net.run(Duration::from_secs(2));
    assert_eq!(net.actives(), vec![0]);
    net.up[0] = false;
    let took = net.until(Duration::from_secs(2), |n| n.actives() == vec![1]);
    assert!(took <= Duration::from_millis(1200), "{took:?}");
    assert_eq!(net.cands[1].lease().epoch, 2);
}

#[test]
fn a_returning_higher_priority_gets_the_role_by_handover_never_two_active() {
    let mut net = Net::new(&[2, 1]);
    net.run(Duration::from_secs(2));
    net.up[0] = false;
    net.until(Duration::from_secs(2), |n| n.actives() == vec![1]);
    net.restart(0);
    // `run` asserts at every step that at most one is active.
    net.run(Duration::from_secs(4));
    assert_eq!(
        net.actives(),
        vec![1],
        "no pre-emption before handover_after"
    );
    net.until(Duration::from_secs(3), |n| n.actives() == vec![0]);
    assert_eq!(net.cands[0].lease().epoch, 3);
    net.run(Duration::from_secs(3));
    assert_eq!(net.actives(), vec![0]);
}

#[test]
fn after_a_partition_heals_the_older_epoch_steps_down() {
    let mut net = Net::new(&[2, 1]);
    net.run(Duration::from_secs(2));
    net.group[1] = 1;
    net.run(Duration::from_secs(2));
    assert_eq!(net.actives(), vec![0, 1], "each side elects its own");
    assert_eq!(net.cands[1].lease().epoch, 2);
    net.group[1] = 0;
    net.step();
    net.step();
    assert_eq!(net.actives(), vec![1], "epoch 2 wins over epoch 1");
    // Then the higher priority gets it back by handover.
    net.until(Duration::from_secs(7), |n| n.actives() == vec![0]);
    assert_eq!(net.cands[0].lease().epoch, 3);
}

#[test]
fn a_lone_candidate_claims_and_status_names_the_active_one() {
    let mut net = Net::new(&[5, 1]);
    net.run(Duration::from_secs(2));
    let s = net.cands[1].status(net.now);
    assert_eq!(s.role, CoordinatorRole::Standby);
    assert_eq!(s.active.unwrap().coordinator_id, "c0");
    assert_eq!(s.peers.len(), 1);
    assert!(s.peers[0].age_s < 0.2);
    let json = serde_json::to_value(net.cands[0].status(net.now)).unwrap();
    assert_eq!(json["role"], "active");
    assert_eq!(json["this"]["epoch"], 1);
}

#[test]
fn a_candidate_that_hears_late_claims_nothing_while_it_listens_longer() {
    let mut net = Net::new(&[2, 1]);
    net.until(Duration::from_secs(2), |n| n.actives() == vec![0]);
    net.up[0] = false;
    net.until(Duration::from_secs(2), |n| n.actives() == vec![1]);
    // c0 comes back deaf for 2.5 s (DDS Security's handshake on a slow link). With the
    // lease timeout as its first listen it would claim a second active role; listening
    // 5 s it hears c1 first and takes the role only by handover.
    let slow = ElectionConfig {
        first_listen: Duration::from_secs(5),
        ..ElectionConfig::default()
    };
    net.restart_with(0, slow, Duration::from_millis(2500));
    net.run(Duration::from_secs(4));
    assert_eq!(net.actives(), vec![1]);
    net.until(Duration::from_secs(10), |n| n.actives() == vec![0]);
}
