"""The ch. 7 hypotheses judged from a study's scene entries."""

from experiments.latdespot_hypotheses import hypotheses


def entry(success, lo, hi, value, half=0.5, infeasible=0.0):
    return {"success_rate": success, "success_rate_ci95": [lo, hi],
            "discounted_value": value, "discounted_value_ci95": half,
            "infeasible_rate": infeasible}


def scenes():
    """Rel-SARSOP ahead of Lift-QMDP in value on ``empty``, behind in success on both;
    Lat-DESPOT best on ``cul_de_sac`` and inside Lift-SARSOP's interval on ``empty``."""
    return {
        "empty": {"rel-sarsop": entry(0.0, 0.0, 0.05, -11.0, infeasible=1.0),
                  "lift-qmdp": entry(0.3, 0.2, 0.4, -15.0),
                  "lift-sarsop": entry(0.9, 0.85, 0.94, -10.0),
                  "lat-despot": entry(0.87, 0.82, 0.91, -10.5)},
        "cul_de_sac": {"rel-sarsop": entry(0.0, 0.0, 0.05, -12.0, infeasible=0.6),
                       "lift-qmdp": entry(0.4, 0.3, 0.5, -12.2),
                       "lift-sarsop": entry(0.5, 0.4, 0.6, -12.0),
                       "lat-despot": entry(0.8, 0.7, 0.86, -10.0)},
    }


def test_h2_and_h3_are_judged_on_value_and_on_success_apart():
    h = hypotheses(scenes())
    assert h["H2"]["scenes"] == {"by_value": ["empty"], "by_success": []}
    assert h["H2"]["shown"] == {"by_value": True, "by_success": False}
    assert h["H3"]["scenes"] == {"by_value": [], "by_success": ["empty", "cul_de_sac"]}


def test_h4_needs_near_best_everywhere_and_the_trap_apart_from_lift_sarsop():
    h = hypotheses(scenes())["H4"]
    assert h["near_best"] == {"empty": True, "cul_de_sac": True} and h["shown"]
    worse = scenes()
    worse["empty"]["lat-despot"] = entry(0.8, 0.7, 0.86, -10.5)  # below 0.85, LS's lower end
    assert not hypotheses(worse)["H4"]["near_best_everywhere"]
    close = scenes()
    close["cul_de_sac"]["lat-despot"] = entry(0.7, 0.58, 0.8, -10.0)  # overlaps LS's
    h = hypotheses(close)["H4"]
    assert h["above_lift_sarsop_on_cul_de_sac"] is False and not h["shown"]


def test_an_infeasible_action_by_a_lattice_policy_breaks_feasible_only():
    assert hypotheses(scenes())["feasible_only"]["holds"]  # Rel-SARSOP's do not count
    bad = scenes()
    bad["empty"]["lift-sarsop"]["infeasible_rate"] = 0.01
    assert not hypotheses(bad)["feasible_only"]["holds"]


def test_missing_policies_leave_their_hypotheses_unjudged():
    only = {s: {"lat-despot": e["lat-despot"]} for s, e in scenes().items()}
    h = hypotheses(only)
    assert h["H2"] is None and h["H3"] is None
    assert h["H4"]["above_lift_sarsop_on_cul_de_sac"] is None and not h["H4"]["shown"]
