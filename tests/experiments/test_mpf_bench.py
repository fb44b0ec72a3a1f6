"""``cmanip bench mpf`` reports the issue's keys (timings themselves are not asserted)."""

from experiments.mpf_bench import run_mpf_bench


def test_bench_reports_every_key(capsys):
    report = run_mpf_bench(repeats=2, seed=1)
    for key in ("cpf_update_ms", "mpf_update_ms", "cpf_update_ms_10k", "mpf_update_ms_10k",
                "transition_particle_mm_per_s"):
        assert report[key] > 0
    assert "MPF 100+25" in capsys.readouterr().out
