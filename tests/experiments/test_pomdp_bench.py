"""``cmanip bench pomdp``'s hand-problem section reports its keys (times are not asserted)."""

from experiments.pomdp_bench import hand_problem_bench
from planning.hand.discretization import HandProblemSpec


def test_hand_problem_bench_reports_every_key(capsys):
    spec = HandProblemSpec(trust_x_m=(0.0, 0.22), trust_y_m=(-0.08, 0.08), samples_per_state=2)
    report = hand_problem_bench(spec=spec, solve_seconds=1.0, repeats=5)
    for key in ("build_s", "qmdp_solve_s", "pomdp_solve_s", "qmdp_act_ms", "pomdp_act_ms",
                "belief_update_ms", "pomdp_to_qmdp_act_ratio"):
        assert report[key] > 0
    assert report["lower_bound"] <= report["upper_bound"]
    assert report["states"] == report["free_states"] + report["contact_states"] + 1
    assert "hand:" in capsys.readouterr().out
