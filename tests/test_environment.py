"""The environment every recorded result carries names the processor, not only its vendor."""

from thrombojax.eval.tables import cpu_model, environment, measured_line

VM = """processor\t: 0
vendor_id\t: AuthenticAMD
cpu family\t: 26
model\t\t: 2
model name\t: AMD EPYC
processor\t: 1
cpu family\t: 25
model\t\t: 1
model name\t: Other
"""


def test_cpu_model_keeps_family_and_model_numbers():
    # the first processor's fields; a VM that names only the vendor is told apart by the numbers
    assert cpu_model(VM) == "AMD EPYC (cpu family 26, model 2)"
    assert cpu_model("model name\t: Some CPU\n") == "Some CPU"


def test_environment_records_the_processor():
    env = environment()
    assert env["cpu"] == cpu_model() and env["cpu"]


def test_measured_line_names_date_processor_load_versions_and_command():
    env = {**environment(), "date": "D", "cpu": "C", "cpu_count": 2, "device": "cpu:x",
           "load_avg_1_5_15": [1.5, 1, 1], "allocator": "tcmalloc", "python": "3.x",
           "jax": "0.y", "command": "run.py a b"}
    assert measured_line(env) == ("Measured D on C (2 cores, cpu:x, load 1.5, allocator "
                                  "tcmalloc); Python 3.x, jax 0.y. Command: run.py a b")
    assert measured_line().startswith("Measured ")
