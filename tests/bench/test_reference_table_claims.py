"""The online claim's paired statistics (``bench/reference_table_claims.py``)."""

import math

from bench.reference_table_claims import paired, summarize


def _draw(draw, online, batch):
    def run(v):
        return {"status": "ok", "squeeze": v} if v is not None else {"status": "diverged"}
    return {"draw": draw, "online": run(online), "nominal": run(9.0),
            "batch_map_sdp_10s": run(batch)}


def test_draws_are_compared_pairwise_and_a_lost_run_is_left_out():
    rows = [_draw(0, 0.02, 0.04), _draw(1, 0.06, 0.02), _draw(2, 0.03, 0.03),
            _draw(3, None, 0.05), _draw(4, 0.01, 0.02)]
    p = paired(rows)
    assert p["compared"] == 4                     # draw 3's online run lost its squeeze
    assert p["within_2x"] == 3                    # draw 1 is 3x its batch
    assert math.isclose(p["worst"], 3.0) and p["worst_draw"] == 1
    # the median of the ratios 0.5, 3, 1, 0.5 (not the ratio of the medians)
    assert math.isclose(p["ratio"][0], 0.75)
    assert p["ratio"][1] <= 0.75 <= p["ratio"][2]
    s = summarize(rows)
    assert s["failed"] == {"online": 1, "nominal": 0, "batch_map_sdp_10s": 0}
    assert math.isclose(s["online_over_batch"], 0.025 / 0.03)


def test_no_pair_when_no_batch_run_finished():
    assert paired([_draw(0, 0.02, None)]) == {"compared": 0}
