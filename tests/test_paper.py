"""The paper's tables (python -m fem_grasp.paper): our figures beside Tables II and III."""





def test_paper_tables_format():
    from fem_grasp import paper

    ok = {"name": "tomato", "young": 1e4, "success": True, "reason": "", "contacts": 11, "squeeze_depth": 0.0175,
          "time": 3.2, "normal_force": 2.5, "rigid_force": 2.9}
    bad = dict(ok, success=False, reason="every contact of finger 1 slides", normal_force=float("nan"))
    text = paper.format_tables([{"name": "tomato", "table_one": bad, "effective": ok}])
    assert "| tomato | (11, 18, 1.86) | fails (every contact of finger 1 slides) | (11, 17.5, 3.2) | 1e+04 |" in text
    assert "| tomato | 2.68 | 2.96 | 2.5 | 2.9 |" in text
