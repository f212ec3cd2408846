"""`version:` upgrade passes run before validation."""


from lbscene.engine.files import load as load_mod
from lbscene.engine.files.load import load_document
from lbscene.schemas import base


def test_upgrade_pass_applied_in_order(minimal_booth, monkeypatch):
    # Pretend the current format is 2 and version 1 spelled the booth name differently.
    monkeypatch.setattr(base, "CURRENT_VERSION", 2)
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace("name: Minimal test booth", "title: Minimal test booth"))

    def v1_to_v2(data):
        data["name"] = data.pop("title")
        return data

    monkeypatch.setitem(load_mod.UPGRADES, ("Booth", 1), v1_to_v2)
    from lbscene.schemas.booth import Booth

    doc = load_document(f, Booth)
    assert doc.model.name == "Minimal test booth" and doc.model.version == 2
