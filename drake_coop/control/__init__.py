"""The paper's per-robot law: model (arm_model), Property 1 (orthogonal), the law at one sample (finger),
its Drake systems (observers (15)-(16), (22); controller (13)) and the alternative sources."""
