"""The characterisation wizard's report page (issue 47, item 25): the maps were a fixed
900 px strip with half the page empty below the table, the table scrolled sideways, and
there was no way to open report.html from it."""

from __future__ import annotations

import pytest
from PySide6.QtCore import QObject, QUrl, Slot
from PySide6.QtGui import QDesktopServices

from tactile_studio.ui.characterise_wizard import CharacteriseWizard

QUICK = {"dwell_s": "0.5", "relax_hold_s": "3", "settle_s": "1", "window_s": "0.2",
         "directions": "+x,+y"}


class Opened(QObject):
    """Qt's own hook for opening file URLs (QDesktopServices.setUrlHandler)."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[QUrl] = []

    @Slot(QUrl)
    def open(self, url: QUrl) -> None:
        self.urls.append(url)


@pytest.fixture
def report(qtbot, tmp_path):
    w = CharacteriseWizard(str(tmp_path / "run"))
    qtbot.addWidget(w)
    w.resize(1000, 760)  # what the main window and the CLI open it at
    w.show()
    w.next()
    w.plan_page.taxels.setText("B2,C3")
    for k, v in QUICK.items():
        w.plan_page.set_param(k, v)
    w.next()
    qtbot.waitUntil(lambda: w.run_page.finished_run, timeout=90000)
    w.next()
    assert w.currentPage() is w.report
    qtbot.wait(50)
    return w


def test_the_table_fits_the_page_the_pictures_fill_the_rest_and_the_files_open(qtbot, report,
                                                                                 tmp_path):
    page, table = report.report, report.report.table
    assert table.horizontalScrollBar().maximum() == 0  # no sideways scrolling
    assert sum(table.columnWidth(c) for c in range(table.columnCount())) <= \
        table.viewport().width()
    rows = table.horizontalHeader().height() + sum(table.rowHeight(r) for r in range(2))
    assert table.height() <= rows + 2 * table.frameWidth() + 4  # as tall as its rows
    # the maps and the chosen taxel's page share what is left, scaled to it
    below = page.height() - table.geometry().bottom()
    for picture in (page.maps, page.taxel_page):
        assert picture.height() > 0.8 * below
        got, room = picture.pixmap().size(), picture.size()
        assert got.width() >= room.width() - 2 or got.height() >= room.height() - 2
    small = page.maps.pixmap().size()
    report.resize(1400, 1000)
    qtbot.waitUntil(lambda: page.maps.pixmap().width() > small.width() * 1.2, timeout=3000)
    assert page.taxel_title.text().startswith("B2")
    table.selectRow(1)
    assert page.taxel_title.text().startswith("C3") and not page.taxel_page.pixmap().isNull()
    # the files are a click away
    opened = Opened()
    QDesktopServices.setUrlHandler("file", opened, "open")
    try:
        report.report.open_report.click()
        report.report.open_folder.click()
    finally:
        QDesktopServices.unsetUrlHandler("file")
    paths = [u.toLocalFile() for u in opened.urls]
    assert paths == [str(tmp_path / "run" / "report.html"), str(tmp_path / "run") + "/"] or \
        paths == [str(tmp_path / "run" / "report.html"), str(tmp_path / "run")]
