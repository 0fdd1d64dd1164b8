"""The environment every recorded result carries names the processor, not only its vendor."""

from thrombojax.eval.tables import cpu_model, environment

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
