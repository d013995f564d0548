"""Where built datasets are kept by default (rp_jax.datasets.loading.default_data_dir)."""

from pathlib import Path

from rp_jax.datasets import loading

ROOT = Path(__file__).resolve().parents[2]


def test_default_data_dir_is_the_checkouts_whatever_the_working_directory(
    tmp_path, monkeypatch
):
    monkeypatch.delenv("RP_JAX_DATA_DIR", raising=False)
    monkeypatch.chdir(tmp_path)
    # A run from another folder finds the datasets built from the checkout's root.
    assert loading.default_data_dir() == ROOT / "data" / "tensorflow_datasets"
    monkeypatch.setenv("RP_JAX_DATA_DIR", str(tmp_path / "elsewhere"))
    assert loading.default_data_dir() == tmp_path / "elsewhere"


def test_an_installed_package_keeps_its_data_in_the_user_cache(tmp_path, monkeypatch):
    site = tmp_path / "site-packages"  # no pyproject.toml beside the package
    monkeypatch.setattr(loading, "_PACKAGE_PARENT", site)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert loading._checkout_root() is None
    assert loading._default_root() == tmp_path / "cache" / "rp_jax"
