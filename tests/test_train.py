"""The shared trainer (rgbd_rs.nn.train) and its checkpoints, on a tiny conv net and a tiny
synthetic regression (learn a fixed 3x3 smoothing). Everything runs on CPU in seconds."""

from __future__ import annotations

import io
import os
import socket
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from torch import nn
from torch.utils.data import Dataset

import rgbd_rs
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.nn import (
    FORMAT,
    TrainConfig,
    load_checkpoint,
    save_checkpoint,
    seed_everything,
    split,
    train,
)

ARCH = "tiny"
NORM = {"mean": 0.5, "std": torch.tensor([0.25, 0.5])}


class Tiny(nn.Module):
    """Two convolutions with dropout between, so resumption must restore the torch RNG."""

    def __init__(self, width: int = 4) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(1, width, 3, padding=1),
            nn.ReLU(),
            nn.Dropout2d(0.1),
            nn.Conv2d(width, 1, 3, padding=1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)  # type: ignore[no-any-return]


class Smoothing(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """(noisy input, its 3x3 box filter); the noise is drawn from numpy's global generator (an
    augmentation resumption must reproduce). ``interrupt_after`` raises KeyboardInterrupt on
    that many-th item fetched, as Ctrl-C would."""

    def __init__(self, n: int = 20, side: int = 8, interrupt_after: int | None = None) -> None:
        g = torch.Generator().manual_seed(1234)
        self.x = torch.rand(n, 1, side, side, generator=g)
        kernel = torch.full((1, 1, 3, 3), 1 / 9)
        self.y = nn.functional.conv2d(self.x, kernel, padding=1)
        self.interrupt_after = interrupt_after
        self.fetched = 0

    def __len__(self) -> int:
        return len(self.x)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        self.fetched += 1
        if self.interrupt_after is not None and self.fetched >= self.interrupt_after:
            raise KeyboardInterrupt
        # the global generator on purpose: resumption must restore its state
        noise = np.random.normal(0, 0.01, self.x[i].shape).astype(np.float32)  # noqa: NPY002
        return self.x[i] + torch.from_numpy(noise), self.y[i]


def mse(output: torch.Tensor, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
    return nn.functional.mse_loss(output, batch[1])


def run(out: Path, config: TrainConfig, *, data: Dataset[Any] | None = None, **kw: Any) -> Any:
    """Seed, build the model, train; return (model, result)."""
    seed_everything(config.seed)
    model = Tiny()
    train_set, val_set = split(data if data is not None else Smoothing(), 0.2, seed=0)
    kw = {"arch": ARCH, "arch_config": {"width": 4}, "normalisation": NORM, **kw}
    return model, train(model, train_set, val_set, mse, config, out, **kw)


def assert_same_weights(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> None:
    assert a.keys() == b.keys()
    for key in a:
        assert torch.equal(a[key], b[key]), key


CONFIG = TrainConfig(epochs=3, batch_size=4, optimizer="adam", lr=1e-2, seed=3, device="cpu")


def test_loss_decreases_and_checkpoint_holds_everything(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    config = TrainConfig(epochs=6, batch_size=4, lr=2e-2, lr_step=3, lr_gamma=0.5, device="cpu")
    model, result = run(tmp_path, config)
    losses = [h.train_loss for h in result.history]
    assert len(losses) == 6 and losses[-1] < 0.3 * losses[0], losses
    assert [h.lr for h in result.history] == pytest.approx([2e-2] * 3 + [1e-2] * 3)
    assert result.best_checkpoint == tmp_path / "best.pt" and result.best_checkpoint.is_file()
    # stderr is not a terminal: no bar, one line per epoch
    lines = capfd.readouterr().err.splitlines()
    assert [line.split(",")[0] for line in lines] == [f"epoch {k}/6" for k in range(1, 7)], lines
    assert all("val loss" in line and line.endswith(" s") for line in lines), lines
    assert f"train loss {losses[-1]:.4g}," in lines[-1] and ", lr 0.01," in lines[-1], lines

    last = load_checkpoint(result.last_checkpoint, arch=ARCH, normalisation_keys=["mean"])
    assert (last.epoch, last.step, last.world_size) == (6, 0, 1)
    assert last.config == config.to_dict() and TrainConfig.from_dict(last.config) == config
    assert last.arch_config == {"width": 4} and last.version == rgbd_rs.__version__
    assert last.git_revision is None or len(last.git_revision) == 40
    assert last.normalisation["mean"] == 0.5
    assert torch.equal(last.normalisation["std"], NORM["std"])
    assert [h["train_loss"] for h in last.history] == losses
    assert_same_weights(last.model_state, model.state_dict())

    best = load_checkpoint(tmp_path / "best.pt", arch=ARCH)
    assert best.epoch == result.best_epoch
    assert best.best_val_loss == result.best_val_loss == min(h.val_loss for h in result.history)
    fresh = Tiny()
    best.stripped().load_weights(fresh)
    assert_same_weights(fresh.state_dict(), best.model_state)
    with pytest.raises(RgbdError, match=r"best\.pt: weights do not fit"):
        best.load_weights(Tiny(width=5))


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_on_a_terminal_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = TrainConfig(**{**CONFIG.to_dict(), "epochs": 1})
    for quiet, shown in ((False, True), (True, False)):
        monkeypatch.setattr(sys, "stderr", Terminal())
        run(tmp_path / str(quiet), config, quiet=quiet)
        text = sys.stderr.getvalue()  # type: ignore[attr-defined]
        assert ("epoch 1/1" in text and "loss=" in text and "val=" in text) == shown, text
        assert "train loss" not in text  # a terminal gets the bar, not the per-epoch lines


def test_epoch_line_says_when_the_epoch_was_resumed() -> None:
    from rgbd_rs.nn.train import _epoch_line

    entry = {"epoch": 2, "train_loss": 0.5, "val_loss": None, "lr": 0.01, "val_metric": 0.9}
    line = _epoch_line(entry, 5, 12.34)
    assert line == "epoch 2/5, train loss 0.5, val metric 0.9, lr 0.01, 12.3 s", line
    assert _epoch_line(entry, 5, 3.0, resumed=7).endswith("3.0 s (resumed after step 7)")


def test_quiet_prints_nothing_off_a_terminal(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    run(tmp_path, TrainConfig(**{**CONFIG.to_dict(), "epochs": 1}), quiet=True)
    assert capfd.readouterr().err == ""


def test_same_seed_gives_identical_weights(tmp_path: Path) -> None:
    config = TrainConfig(**{**CONFIG.to_dict(), "optimizer": "sgd", "grad_clip": 0.5})
    a, _ = run(tmp_path / "a", config)
    b, _ = run(tmp_path / "b", config)
    assert_same_weights(a.state_dict(), b.state_dict())
    c, _ = run(tmp_path / "c", TrainConfig(**{**config.to_dict(), "seed": 4}))
    assert not torch.equal(a.state_dict()["net.0.weight"], c.state_dict()["net.0.weight"])


def test_interrupted_and_resumed_equals_uninterrupted(tmp_path: Path) -> None:
    config = TrainConfig(
        **{**CONFIG.to_dict(), "optimizer": "sgd", "lr_step": 1, "checkpoint_steps": 3}
    )
    whole, whole_result = run(tmp_path / "whole", config)
    # 16 training items in batches of 4: 4 steps an epoch, each fetching 4 items (+1 validation
    # batch of 4). Interrupt in epoch 2's fourth step: last.pt is from its third.
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path / "cut", config, data=Smoothing(interrupt_after=(16 + 4) + 3 * 4 + 2))
    cut = load_checkpoint(tmp_path / "cut" / "last.pt")
    assert (cut.epoch, cut.step) == (1, 3)
    seed_everything(99)  # the resumed run must take nothing from the caller's RNG
    model = Tiny()
    train_set, val_set = split(Smoothing(), 0.2, seed=0)
    resumed = train(
        model, train_set, val_set, mse, config, tmp_path / "cut",
        arch=ARCH, arch_config={"width": 4}, normalisation=NORM,
    )  # fmt: skip
    assert_same_weights(model.state_dict(), whole.state_dict())
    assert resumed.history == whole_result.history
    for name in ("last.pt", "best.pt"):
        assert_same_weights(
            load_checkpoint(tmp_path / "cut" / name).model_state,
            load_checkpoint(tmp_path / "whole" / name).model_state,
        )
    # A finished run resumes to itself at once.
    again = Tiny()
    assert train(
        again, train_set, val_set, mse, config, tmp_path / "cut",
        arch=ARCH, arch_config={"width": 4}, normalisation=NORM,
    ) == resumed  # fmt: skip
    assert_same_weights(again.state_dict(), whole.state_dict())


def test_resume_refuses_another_setup(tmp_path: Path) -> None:
    run(tmp_path, CONFIG)
    last = tmp_path / "last.pt"
    cases: list[tuple[dict[str, Any], TrainConfig, str]] = [
        ({"arch": "other"}, CONFIG, "arch 'tiny' in the checkpoint, 'other' now"),
        ({"arch_config": {"width": 8}}, CONFIG, r"arch_config\['width'\] differs: 4 -> 8"),
        ({"normalisation": {"mean": 0.5}}, CONFIG, r"normalisation\['std'\] differs"),
        ({}, TrainConfig(**{**CONFIG.to_dict(), "lr": 0.5}), r"config\['lr'\] differs"),
    ]
    for kw, config, what in cases:
        with pytest.raises(RgbdError, match=what) as err:
            run(tmp_path, config, **kw)
        assert str(last) in str(err.value) and "resume=False" in str(err.value)
    # Fields that do not change the trajectory may change; resume=False starts afresh.
    run(tmp_path, TrainConfig(**{**CONFIG.to_dict(), "checkpoint_steps": 2}))
    _, fresh = run(tmp_path, TrainConfig(**{**CONFIG.to_dict(), "epochs": 1}), resume=False)
    assert len(fresh.history) == 1 and load_checkpoint(last).epoch == 1


def test_load_checkpoint_errors_name_the_file(tmp_path: Path) -> None:
    _, result = run(tmp_path / "run", TrainConfig(**{**CONFIG.to_dict(), "epochs": 1}))
    good = result.last_checkpoint
    with pytest.raises(RgbdError, match="checkpoint of architecture 'tiny', expected 'other'"):
        load_checkpoint(good, arch="other")
    with pytest.raises(RgbdError, match=r"normalisation lacks \['sigma'\]"):
        load_checkpoint(good, normalisation_keys=["mean", "sigma"])

    missing = tmp_path / "nothing.pt"
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"\x00not a checkpoint" * 10)
    empty = tmp_path / "empty.pt"
    empty.write_bytes(b"")
    zipped = tmp_path / "zipped.pt"
    zipped.write_bytes(b"PK\x03\x04 not really a zip archive")
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(2)}, other)

    class Payload:  # unpickling it would run code: weights_only must refuse
        def __reduce__(self) -> tuple[Any, ...]:
            return (os.system, ("echo pwned",))

    unsafe = tmp_path / "unsafe.pt"
    torch.save({"format": FORMAT, "x": Payload()}, unsafe)
    no_norm = tmp_path / "no_norm.pt"
    data = torch.load(good, weights_only=True)
    del data["normalisation"]
    torch.save(data, no_norm)
    for path, what in [
        (missing, "checkpoint file not found"),
        (tmp_path, r"is a folder, expected a checkpoint file \(\.pt\)"),
        (garbage, r"not a readable rgbd_rs checkpoint \(it is not a torch checkpoint\)"),
        (unsafe, r"not a readable rgbd_rs checkpoint \(it holds Python objects that are unsafe"),
        (empty, r"not a readable rgbd_rs checkpoint \(it ends early: truncated or empty\?\)"),
        (zipped, r"not a readable rgbd_rs checkpoint \(it is not a torch checkpoint\)"),
        (other, "format tag None, expected 'rgbd_rs.checkpoint/1'"),
        (no_norm, "checkpoint has no normalisation"),
    ]:
        with pytest.raises(RgbdError, match=what) as err:
            load_checkpoint(path, arch=ARCH)
        assert str(path) in str(err.value)
        # Our words, not torch's internals.
        for leak in ("PytorchStreamReader", "inline_container", "weights_only", "enforce fail"):
            assert leak not in str(err.value)
    # save_checkpoint round-trips and leaves no temporary file behind.
    copy = save_checkpoint(load_checkpoint(good).stripped(), tmp_path / "sub" / "copy.pt")
    assert load_checkpoint(copy).optimizer_state is None
    assert [p.name for p in copy.parent.iterdir()] == ["copy.pt"]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("epochs", 0), ("epochs", 1.5), ("batch_size", 0), ("optimizer", "rmsprop"),
        ("lr", 0.0), ("lr", "big"), ("lr", float("nan")), ("momentum", 1.0),
        ("weight_decay", -1.0), ("lr_step", -1), ("lr_gamma", 0.0), ("seed", -1),
        ("seed", 2**32), ("num_workers", -1), ("checkpoint_steps", -2), ("grad_clip", 0.0),
        ("device", "tpu"), ("device", "cuda:x"), ("device", None), ("epochs", True),
    ],
)  # fmt: skip
def test_config_validation_names_the_field(field: str, value: object) -> None:
    with pytest.raises(InvalidArgumentError, match=f"^{field}: got"):
        TrainConfig(**{field: value})


def test_bad_arguments(tmp_path: Path) -> None:
    TrainConfig(device="cuda:1", lr=1, grad_clip=2)  # accepted (ints become floats)
    assert isinstance(TrainConfig(lr=1).lr, float)
    with pytest.raises(InvalidArgumentError, match="unknown fields"):
        TrainConfig.from_dict({"epochs": 2, "nesterov": True})
    data = Smoothing()
    with pytest.raises(InvalidArgumentError, match=r"normalisation\['mean'\]: got ndarray"):
        run(tmp_path, CONFIG, normalisation={"mean": np.zeros(3)})
    with pytest.raises(InvalidArgumentError, match="arch: got ''"):
        run(tmp_path, CONFIG, arch="")
    with pytest.raises(InvalidArgumentError, match="train_set: got list"):
        train(Tiny(), [1, 2], None, mse, CONFIG, tmp_path, arch=ARCH, arch_config={},
              normalisation={})  # type: ignore[arg-type]  # fmt: skip
    with pytest.raises(RgbdError, match="loss_fn: returned nan at epoch 1 step 1"):
        train(Tiny(), data, None, lambda out, b: out.sum() * np.nan, CONFIG, tmp_path / "nan",
              arch=ARCH, arch_config={}, normalisation={})  # fmt: skip
    for fraction in (0, 1, 1.5):
        with pytest.raises(InvalidArgumentError, match="fraction: got"):
            split(data, fraction)


def test_split_is_deterministic_and_disjoint() -> None:
    data = Smoothing(n=10)
    a_train, a_val = split(data, 0.3, seed=5)
    b_train, b_val = split(data, 0.3, seed=5)
    assert a_train.indices == b_train.indices and a_val.indices == b_val.indices
    assert len(a_val) == 3 and sorted([*a_train.indices, *a_val.indices]) == list(range(10))
    assert split(data, 0.3, seed=6)[1].indices != a_val.indices


DDP_SCRIPT = """
import faulthandler
import os
import sys

import torch
import torch.distributed as dist

sys.path.insert(0, {tests!r})
from test_train import ARCH, NORM, Smoothing, Tiny, mse
from rgbd_rs.nn import TrainConfig, is_main_process, seed_everything, split, train

faulthandler.dump_traceback_later(100, exit=True)  # a hang ends with the stacks, not orphans
root, rank = sys.argv[1], int(os.environ["RANK"])
config = TrainConfig(epochs=2, batch_size=3, lr=1e-2, checkpoint_steps=2, device="cpu")


def fit(out, data):
    seed_everything(rank)  # different initial weights per rank: DDP must broadcast rank 0's
    model = Tiny()
    train_set, val_set = split(data, 0.2, seed=0)
    result = train(model, train_set, val_set, mse, config, out, arch=ARCH,
                   arch_config={{"width": 4}}, normalisation=NORM)
    return model, result


model, result = fit(f"{{root}}/whole", Smoothing())
assert not dist.is_initialized()  # train() destroyed the group it created
assert is_main_process() == (rank == 0)
val = [h.val_loss for h in result.history]
torch.save({{"state": model.state_dict(), "val": val}}, f"{{root}}/whole/rank{{rank}}.pt")

# Per rank and epoch: 8 training items in steps of 3, 3, 2 (last.pt after step 2), then 2
# validation items; interrupt in epoch 2's third step, then resume in a group the caller made.
try:
    fit(f"{{root}}/cut", Smoothing(interrupt_after=10 + 6 + 2))
    raise AssertionError("not interrupted")
except KeyboardInterrupt:
    assert not dist.is_initialized()
dist.init_process_group("gloo")
model, _ = fit(f"{{root}}/cut", Smoothing())
assert dist.is_initialized()
torch.save({{"state": model.state_dict()}}, f"{{root}}/cut/rank{{rank}}.pt")
dist.destroy_process_group()
"""


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.skipif(
    not torch.distributed.is_available() or not torch.distributed.is_gloo_available(),
    reason="this torch build has no torch.distributed with the gloo backend",
)
def test_ddp_two_cpu_processes_identical_weights_and_resume(tmp_path: Path) -> None:
    script = tmp_path / "ddp_train.py"
    script.write_text(textwrap.dedent(DDP_SCRIPT.format(tests=str(Path(__file__).parent))))
    env = {
        **os.environ,
        "MASTER_ADDR": "127.0.0.1",
        "GLOO_SOCKET_IFNAME": "lo",
        "OMP_NUM_THREADS": "1",
        "PYTHONWARNINGS": "error",
    }
    cmd = [
        sys.executable, "-m", "torch.distributed.run", "--nnodes=1", "--nproc_per_node=2",
        "--master_addr=127.0.0.1", f"--master_port={free_port()}", str(script),
    ]  # fmt: skip
    log = tmp_path / "torchrun.log"
    with log.open("w") as f:
        proc = subprocess.Popen([*cmd, str(tmp_path)], env=env, stdout=f, stderr=subprocess.STDOUT)
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            proc.terminate()  # torchrun passes it on to its workers
            proc.wait(timeout=30)
    out = log.read_text()
    assert proc.returncode == 0, out[-4000:]
    whole = [torch.load(tmp_path / "whole" / f"rank{r}.pt", weights_only=True) for r in (0, 1)]
    assert_same_weights(whole[0]["state"], whole[1]["state"])
    assert whole[0]["val"] == whole[1]["val"]  # validation loss averaged over both ranks
    last = load_checkpoint(tmp_path / "whole" / "last.pt", arch=ARCH)
    assert (last.epoch, last.world_size) == (2, 2)
    assert_same_weights(last.model_state, whole[0]["state"])
    # Interrupted mid-epoch and resumed on 2 processes: the very same weights.
    for r in (0, 1):
        cut = torch.load(tmp_path / "cut" / f"rank{r}.pt", weights_only=True)
        assert_same_weights(cut["state"], whole[0]["state"])


@pytest.mark.parametrize(
    ("device", "local", "index"),
    [("auto", "0", 0), ("cuda", "0", 0), ("cuda", "2", 2), ("cuda:1", "0", 1)],
)
def test_a_gpu_device_gets_its_index(
    device: str, local: str, index: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # torch.cuda.set_device refuses a device without an index; on a CPU machine CUDA is faked.
    from rgbd_rs.nn import distributed

    chosen: list[torch.device] = []
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 4)
    monkeypatch.setattr(torch.cuda, "set_device", chosen.append)
    monkeypatch.setenv("LOCAL_RANK", local)
    monkeypatch.delenv("WORLD_SIZE", raising=False)
    g = distributed._setup(device)
    assert chosen == [torch.device("cuda", index)] and g.device == chosen[0]


def test_a_gpu_device_is_checked_against_the_machine(monkeypatch: pytest.MonkeyPatch) -> None:
    from rgbd_rs.nn import distributed

    chosen: list[torch.device] = []
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)
    monkeypatch.setattr(torch.cuda, "set_device", chosen.append)
    monkeypatch.delenv("WORLD_SIZE", raising=False)
    monkeypatch.setenv("LOCAL_RANK", "0")
    with pytest.raises(InvalidArgumentError, match=r"device: got 'cuda:5', expected one of .* 2"):
        distributed._setup("cuda:5")
    monkeypatch.setenv("LOCAL_RANK", "3")  # more processes than GPUs
    with pytest.raises(InvalidArgumentError, match=r"'cuda:3' \(LOCAL_RANK=3\)"):
        distributed._setup("cuda")
    # Under torchrun each process takes GPU LOCAL_RANK: a fixed index would put all on one GPU.
    monkeypatch.setenv("WORLD_SIZE", "2")
    with pytest.raises(InvalidArgumentError, match=r"'cuda:0' with WORLD_SIZE=2"):
        distributed._setup("cuda:0")
    assert chosen == []
