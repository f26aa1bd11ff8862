"""The model extension seam: entry-point registry, register_model, the Learner protocol, the
declared facts the pipeline reads, and check_model catching a broken declaration.

Budget: ~5 s without the slow check_model sweep over every built-in (~40 s on 2 shared cores).
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from importlib.metadata import entry_points

import pytest
import torch

from tactile_studio.errors import UserError
from tactile_studio.learn import Learner, ModelCheckError, check_model
from tactile_studio.learn.deploy.export import int8_format
from tactile_studio.learn.deploy.streaming import StreamingPredictor
from tactile_studio.learn.experiments.sweep import task_gpus
from tactile_studio.learn.experiments.train_job import model_settings
from tactile_studio.learn.learners.contract import Fitted
from tactile_studio.learn.learners.families import available_models, make_learner
from tactile_studio.learn.models import (
    GROUP,
    MODELS,
    Streaming,
    get_model_spec,
    model_names,
    register_model,
    unregister_model,
)

BUILT_INS = ("cnn3d", "cnn_transformer", "cnn1d", "mts3d", "sefusion")


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(1)  # the 2 cores are shared by the whole team


@pytest.fixture
def registered():
    """Register specs for one test and forget them afterwards."""
    names: list[str] = []

    def add(spec, **kw):
        names.append(spec.name)
        return register_model(spec, **kw)

    yield add
    for name in names:
        unregister_model(name)


def test_built_in_models_register_through_the_entry_point_group():
    declared = {ep.name: ep.value for ep in entry_points(group=GROUP)}
    for name in BUILT_INS:
        assert declared[name] == f"tactile_studio.learn.models.{name}:MODEL"
        assert get_model_spec(name).name == name
    assert set(BUILT_INS) <= set(model_names())


def test_listing_models_imports_no_model_module_and_learn_imports_no_torch():
    code = ("import sys\n"
            "import tactile_studio.learn.data.splits\n"
            "assert 'torch' not in sys.modules, 'learn/__init__ pulled in torch'\n"
            "from tactile_studio.learn.models import model_names\n"
            "names = model_names()\n"
            "assert 'cnn3d' in names, names\n"
            "loaded = [m for m in sys.modules if m.startswith('tactile_studio.learn.models.')\n"
            "          and m.rsplit('.', 1)[1] in names]\n"
            "assert not loaded, loaded\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_register_model_adds_a_name_everywhere_and_rejects_clashes(registered):
    spec = dataclasses.replace(get_model_spec("cnn1d"), name="cnn1d_copy",
                               description="a copy of cnn1d")
    assert registered(spec) is spec
    assert MODELS["cnn1d_copy"] is spec and "cnn1d_copy" in model_names()
    assert available_models()["cnn1d_copy"] == "a copy of cnn1d"
    assert make_learner("cnn1d_copy", "tiny").name == "cnn1d_copy"
    with pytest.raises(ValueError, match="already registered"):
        register_model(dataclasses.replace(spec, description="another"))
    with pytest.raises(ValueError, match="already registered"):
        register_model(dataclasses.replace(spec, name="cnn3d"))
    for bad in ("rf", "Big Model"):
        with pytest.raises(ValueError, match="model name"):
            register_model(dataclasses.replace(spec, name=bad))
    with pytest.raises(TypeError, match="ModelSpec"):
        register_model({"name": "dict_model"})
    unregister_model("cnn1d_copy")
    assert "cnn1d_copy" not in MODELS
    with pytest.raises(UserError, match=r"^unknown model 'cnn1d_copy' \(available: .*cnn1d"):
        get_model_spec("cnn1d_copy")
    with pytest.raises(UserError, match=r"^unknown model 'cnn1d_copy' \(available: .*rf, et, knn"):
        make_learner("cnn1d_copy")


def test_torch_and_baseline_learners_satisfy_the_learner_protocol_with_declared_facts():
    ct, cnn1d, rf = (make_learner(n, "tiny") for n in ("cnn_transformer", "cnn1d", "rf"))
    for learner in (ct, cnn1d, rf):
        assert isinstance(learner, Learner)
    assert (ct.facts.view, ct.facts.sliding, ct.facts.cached, ct.facts.window) == \
        ("windows", True, True, 9)
    assert ct.windowed and ct.max_epochs == 40 and ct.facts.quantizable
    assert (cnn1d.facts.view, cnn1d.facts.sliding, cnn1d.facts.window) == ("slices", False, None)
    assert not cnn1d.windowed and cnn1d.facts.export == ("onnx",)
    assert cnn1d.facts.option_help["kernel"].startswith("kernel length")
    assert (rf.facts.view, rf.facts.quantizable, rf.max_epochs) == ("features", False, 1)
    assert rf.facts.option_help["n_estimators"] == "trees in the forest"
    # the train panel's help comes from the facts, for torch models and baselines alike
    helps = {k: h for k, _, h in model_settings("knn", "tiny")}
    assert helps["n_neighbors"] == "neighbours that vote"
    # a view override changes the declared sliding window with it
    assert make_learner("cnn_transformer", "tiny", {"view_frames": 12}).facts.window == 12


def test_streaming_and_export_read_the_declaration_not_the_network(registered):
    base = get_model_spec("cnn_transformer")
    plain = registered(dataclasses.replace(base, name="ct_uncached", streaming=Streaming(),
                                           gpus=1.0))
    view = base.view("tiny")
    # the same network (it has frame_features / classify_embeddings) ...
    cached_model = base.build(3, 3, (6, 6), "tiny").eval()
    plain_model = plain.build(3, 3, (6, 6), "tiny").eval()
    assert callable(plain_model.frame_features)
    # ... is cached only when its declaration says so
    assert StreamingPredictor(cached_model, view).cached
    assert not StreamingPredictor(plain_model, view).cached
    assert not StreamingPredictor(cached_model, view, streaming=Streaming(True, False)).cached
    assert task_gpus("ct_uncached") == 1.0 and task_gpus("cnn_transformer") == 0.0
    assert task_gpus("cnn1d", "cuda:0") == 1.0 and task_gpus("rf", "cuda") == 0.0
    assert int8_format("mts3d") == "qdq" and int8_format("cnn1d") == "qoperator"
    torchscript_only = registered(dataclasses.replace(base, name="ct_script",
                                                      export=("torchscript",), quantizable=False))
    with pytest.raises(UserError, match="does not export to ONNX"):
        StreamingPredictor(torchscript_only.build(3, 3, (6, 6), "tiny"), view, backend="onnx")


def test_check_model_lists_every_problem_of_a_broken_declaration():
    base = get_model_spec("cnn1d")
    help_ = dict(base.option_help)
    del help_["kernel"]
    broken = dataclasses.replace(
        base, name="broken", description="", option_help={**help_, "colour": "paint it"},
        streaming=Streaming(sliding=False, cached=True), export=("tflite",), int8_format="fast")
    with pytest.raises(ModelCheckError) as err:
        check_model(broken)
    text = str(err.value)
    assert text.startswith("model broken: 7 problem(s)")
    for part in ("description: give one line", "add one line of help for kernel",
                 "options the model does not have: colour", "export ('tflite',)",
                 "quantizable needs export to onnx", "int8_format 'fast'",
                 "streaming.cached needs streaming.sliding"):
        assert part in text, part
    with pytest.raises(ModelCheckError, match=r"unknown model 'nope'"):
        check_model("nope")


def test_check_model_catches_a_cached_claim_the_network_cannot_keep():
    lying = dataclasses.replace(get_model_spec("cnn_transformer"), name="lying",
                                builder=get_model_spec("cnn3d").builder,
                                options=get_model_spec("cnn3d").options,
                                option_help=get_model_spec("cnn3d").option_help)
    with pytest.raises(ModelCheckError, match="no frame_features, classify_embeddings"):
        check_model(lying)


@pytest.mark.slow
@pytest.mark.parametrize("name", [*BUILT_INS, "rf", "et", "knn"])
def test_every_built_in_model_passes_check_model(name):
    observed = check_model(name)
    assert observed["samples"] >= 18  # 18 synthetic trials, windows give more samples
    assert 0.0 <= observed["train_accuracy"] <= 1.0
    if name in BUILT_INS:
        assert observed["parameters"][("tiny", 3)] > 0


def test_fitted_models_satisfy_the_fitted_protocol():
    from tactile_studio.learn.learners.baselines import BaselineModel
    from tactile_studio.learn.learners.families import TorchFitted

    assert isinstance(TorchFitted(torch.nn.Linear(2, 2), "cpu"), Fitted)
    assert isinstance(BaselineModel("rf", {}, 3), Fitted)
