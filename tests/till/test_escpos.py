"""The ESC/POS decoder (serveur.till.escpos) on the jobs points of sale send (tests/till/jobs.py).

Pure: bytes in, lines out. The lines must be what the paper shows: every command's parameters
and data skipped (never a stray byte of them in the text), the code pages the job selects
decoded right, a ticket per cut, and no crash nor endless loop on whatever a socket delivers.
"""

from __future__ import annotations

import time
import unicodedata

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from serveur.till.escpos import ENCODINGS, PrintedTicket, decode_job, status_replies
from tests.till import jobs
from tests.till.jobs import GARBLED, JOBS, LAYOUTS, TRUNCATED, Job

# A decoder that loops forever fails here rather than at the suite's 180 s.
pytestmark = pytest.mark.timeout(10)

SINGLE_BYTE = ("auto", "cp437", "cp850", "cp1252")
LOW_QUOTE = "\u201a"  # byte 0x82 in WPC1252 (é in PC437 and PC850)
EVERY_JOB = (*JOBS, GARBLED)


def printed(tickets: list[PrintedTicket]) -> list[tuple[str, ...]]:
    return [t.lines for t in tickets]


def unprintable(text: str) -> list[str]:
    """The characters of ``text`` no printer prints (controls) or that break a line."""
    return [c for c in text if unicodedata.category(c) in ("Cc", "Zl", "Zp")]


def assert_well_formed(tickets: list[PrintedTicket]) -> None:
    for ticket in tickets:
        assert ticket.lines, "a ticket holds lines"
        assert ticket.lines[0].strip() and ticket.lines[-1].strip(), "blank paper is no line"
        for line in ticket.lines:
            assert not unprintable(line), f"control characters in {line!r}"
            assert line == line.rstrip()
        assert ticket.unknown >= 0


# --- Every job: its lines exactly as printed ----------------------------------------------


@pytest.mark.parametrize("job", JOBS, ids=lambda j: j.name)
def test_each_job_prints_its_tickets_line_for_line(job: Job) -> None:
    tickets = decode_job(job.data, job.encoding)
    assert printed(tickets) == [t.lines for t in job.tickets]
    assert [t.cut for t in tickets] == [t.cut for t in job.tickets]
    assert [t.unknown for t in tickets] == [0] * len(tickets), "every command is known"
    assert [t.text for t in tickets] == ["\n".join(t.lines) for t in job.tickets]


@pytest.mark.parametrize("job", [j for j in JOBS if j.in_band], ids=lambda j: j.name)
def test_a_job_that_selects_its_code_pages_reads_alike_on_any_single_byte_printer(
    job: Job,
) -> None:
    want = printed(decode_job(job.data, job.encoding))
    for encoding in SINGLE_BYTE:
        assert printed(decode_job(job.data, encoding)) == want, encoding


@pytest.mark.parametrize("job", EVERY_JOB, ids=lambda j: j.name)
@pytest.mark.parametrize("encoding", ENCODINGS)
def test_no_control_character_nor_command_reaches_the_text(job: Job, encoding: str) -> None:
    tickets = decode_job(job.data, encoding)
    assert_well_formed(tickets)
    text = "\n".join(t.text for t in tickets)
    # what the jobs carry as commands' data: the QR code's link, the barcode's digits
    assert "https" not in text and "pos.example" not in text
    assert "{B" not in text


# --- Code pages -----------------------------------------------------------------------------


def test_the_jobs_carry_the_code_pages_they_claim() -> None:
    """The fixtures hold what the tests below rely on: each code page's bytes, and its command."""
    square = jobs.SQUARE_ORDER.data
    assert b"\x1bt\x00" in square and "Crème brûlée".encode("cp437") in square
    assert "Jalapeño".encode("cp437") in square
    first = jobs.CHECK_FIRST.data
    assert b"\x1bt\x10" in first and "Crème brûlée".encode("cp1252") in first
    cp850 = jobs.CHECK_CP850.data
    assert b"\x1bt\x02" in cp850 and "Pão de queijo".encode("cp850") in cp850
    assert "Pão".encode("cp850") != "Pão".encode("cp1252")  # and PC437 has no ã
    fs = jobs.TM_FS.data
    assert jobs.KANJI_ON + "2 叉烧包".encode("gb18030") + jobs.KANJI_OFF in fs
    assert jobs.UTF8_ON in jobs.TM_UTF8.data and "肉骨茶".encode() in jobs.TM_UTF8.data
    setting = jobs.TM_STATUS.data
    assert jobs.KANJI_ON not in setting and "炒粿条".encode("gb18030") in setting


def test_accented_dishes_decode_from_each_single_byte_page() -> None:
    assert "2 x Crème brûlée" in jobs.SQUARE_ORDER.lines  # PC437 (ESC t 0)
    assert "Crème brûlée x1                       9.00" in jobs.CHECK_FIRST.lines  # WPC1252
    assert decode_job(jobs.CHECK_FIRST.data)[0].lines == jobs.CHECK_FIRST.lines
    lines = decode_job(jobs.CHECK_CP850.data)[0].lines  # PC850 (ESC t 2)
    assert "Pão de queijo x3                      7.50" in lines
    assert "Crème brûlée x2                      18.00" in lines


def test_esc_t_selects_the_page_of_the_bytes_that_follow() -> None:
    data = b"\x1bt\x00\x82\n\x1bt\x10\x82\n\x1bt\x02\xc6\n"
    assert printed(decode_job(data, "cp1252")) == [("é", LOW_QUOTE, "ã")]


def test_an_unknown_code_page_is_counted_and_the_printer_setting_applies() -> None:
    (ticket,) = decode_job(b"\x1bt\xc8Caf\x82\n", "cp437")
    assert ticket.lines == ("Café",)
    assert ticket.unknown == 1


def test_chinese_between_fs_and_and_fs_dot_is_gb18030_whatever_the_setting() -> None:
    data = b"A" + jobs.KANJI_ON + "叉烧包".encode("gb18030") + jobs.KANJI_OFF + b"\x82\n"
    for encoding in SINGLE_BYTE:
        want = "A叉烧包" + ("é" if encoding in ("auto", "cp437", "cp850") else LOW_QUOTE)
        assert printed(decode_job(data, encoding)) == [(want,)], encoding


def test_a_printer_set_to_chinese_reads_gb18030_until_fs_dot_even_after_esc_t() -> None:
    """A Chinese printer is in double-byte mode from power-on; ESC t picks the single-byte
    page used once FS . leaves it. python-escpos sends ESC t 0 before its ASCII text."""
    assert b"\x1bt\x00" in jobs.TM_STATUS.data
    gb = "少辣".encode("gb18030")
    data = b"\x1bt\x00" + gb + b"\n" + jobs.KANJI_OFF + b"\x1bt\x10\xe9\n"
    assert printed(decode_job(data, "gb18030")) == [("少辣", "é")]
    assert printed(decode_job(jobs.TM_STATUS.data, "gb18030")) == [jobs.TM_STATUS.lines]


def test_the_printer_setting_decides_when_the_job_says_nothing() -> None:
    """The job of a Chinese printer that never sends FS &: mojibake unless the site says so."""
    (auto,) = decode_job(jobs.TM_STATUS.data, "auto")
    assert jobs.TM_STATUS.lines[1] not in auto.lines  # the table line
    assert auto.lines[0] != "厨房单"
    assert printed(decode_job(jobs.TM_STATUS.data, "gb18030")) == [jobs.TM_STATUS.lines]


def test_utf8_by_fs_c_function_48_and_back_to_one_byte() -> None:
    utf8 = "Jalapeño 叉烧".encode()
    data = jobs.UTF8_ON + utf8 + b"\n" + b"\x1c(C\x02\x00\x30\x01" + b"\xa4\n"
    assert printed(decode_job(data, "cp437")) == [("Jalapeño 叉烧", "ñ")]
    assert printed(decode_job(jobs.TM_UTF8.data, "cp437")) == [jobs.TM_UTF8.lines]


def test_auto_reads_utf8_where_valid_else_pc437() -> None:
    assert printed(decode_job("Jalapeño\n".encode())) == [("Jalapeño",)]
    assert printed(decode_job(b"Jalape\xa4o\n")) == [("Jalapeño",)]


def test_esc_at_clears_the_unprinted_line_and_returns_to_the_printer_setting() -> None:
    assert printed(decode_job(b"Table\x1b@12\n")) == [("12",)]
    data = b"\x1bt\x10\xe9\n\x1b@\xe9\n" + jobs.KANJI_ON + b"\x1b@\x82\n"
    assert printed(decode_job(data, "cp437")) == [("é", "Θ", "é")]


def test_an_unknown_encoding_setting_is_refused() -> None:
    with pytest.raises(ValueError, match="encoding"):
        decode_job(b"x", "latin-1")


# --- Commands never leak: each command between two halves of a word --------------------------

# (what, the command's bytes, how it shows: "" nothing, "line" a new line, "cut" a new ticket,
# "clear" the line before it dropped). Parameters are printable characters wherever the
# command allows, so a decoder that does not skip them prints them. Formats: Epson's ESC/POS
# reference (TM-T88 series specification), and for ESC B, FS & / FS . / FS 2 the Chinese
# printers' manuals (HPRT, SPRT, HCC).
COMMANDS: list[tuple[str, bytes, str]] = [
    ("ESC ! n print mode", b"\x1b!0", ""),
    ("ESC - n underline", b"\x1b-1", ""),
    ("ESC E n emphasized", b"\x1bE1", ""),
    ("ESC G n double-strike", b"\x1bG1", ""),
    ("ESC M n font", b"\x1bM1", ""),
    ("ESC a n justification", b"\x1ba1", ""),
    ("ESC R n international set", b"\x1bR0", ""),
    ("ESC 3 n line spacing", b"\x1b3<", ""),
    ("ESC 2 default spacing", b"\x1b2", ""),
    ("ESC SP n right spacing", b"\x1b 1", ""),
    ("ESC { n upside-down", b"\x1b{1", ""),
    ("ESC V n rotation", b"\x1bV1", ""),
    ("ESC r n colour", b"\x1br1", ""),
    ("ESC % n user set", b"\x1b%1", ""),
    ("ESC ? n cancel user char", b"\x1b?A", ""),
    ("ESC = n peripheral", b"\x1b=1", ""),
    ("ESC U n unidirectional", b"\x1bU1", ""),
    ("ESC T n page direction", b"\x1bT1", ""),
    ("ESC L / ESC S page mode", b"\x1bL\x1bS", ""),
    ("ESC < home", b"\x1b<", ""),
    ("ESC $ nL nH position", b"\x1b$00", ""),
    ("ESC \\ nL nH relative position", b"\x1b\\00", ""),
    ("ESC c 3 n paper sensors", b"\x1bc30", ""),
    ("ESC c 5 n panel buttons", b"\x1bc51", ""),
    ("ESC p m t1 t2 drawer pulse", b"\x1bp022", ""),
    ("ESC B n t beeper", b"\x1bB32", ""),
    ("ESC W page area", b"\x1bWABCDEFGH", ""),
    ("ESC D tab stops, NUL-ended", b"\x1bD()*\x00", ""),
    ("ESC * 8-dot bit image", b"\x1b*\x00\x03\x00xyz", ""),
    ("ESC * 24-dot bit image", b"\x1b*!\x02\x00XYZ\nVW", ""),
    ("ESC & user characters", b"\x1b&\x03AB\x02ZZ\nZZZ\x01QQQ", ""),
    ("ESC ( A beeper", b"\x1b(A\x04\x000A33", ""),
    ("ESC t n code page", b"\x1bt\x00", ""),
    ("ESC J n print and feed dots", b"\x1bJ0", "line"),
    ("ESC d n print and feed lines", b"\x1bd\x01", "line"),
    ("ESC @ initialize", b"\x1b@", "clear"),
    ("ESC i cut", b"\x1bi", "cut"),
    ("ESC m partial cut", b"\x1bm", "cut"),
    ("GS ! n character size", b'\x1d!"', ""),
    ("GS B n reverse", b"\x1dB1", ""),
    ("GS H n HRI position", b"\x1dH2", ""),
    ("GS h n barcode height", b"\x1dhd", ""),
    ("GS w n barcode width", b"\x1dw3", ""),
    ("GS f n HRI font", b"\x1df0", ""),
    ("GS a n status back", b"\x1da0", ""),
    ("GS b n smoothing", b"\x1db1", ""),
    ("GS r n transmit status", b"\x1dr1", ""),
    ("GS I n printer ID", b"\x1dIA", ""),
    ("GS T n line start", b"\x1dT1", ""),
    ("GS / m downloaded image", b"\x1d/0", ""),
    ("GS L nL nH left margin", b"\x1dL00", ""),
    ("GS W nL nH print width", b"\x1dW00", ""),
    ("GS P x y motion units", b"\x1dP00", ""),
    ("GS ^ r t m macro", b"\x1d^123", ""),
    ("GS : macro definition", b"\x1d:", ""),
    ("GS g 0 m nL nH counter", b"\x1dg0\x00AB", ""),
    ("GS * x y downloaded image", b"\x1d*\x01\x01ABCD\nFGH", ""),
    ("GS v 0 raster image", b"\x1dv00\x02\x00\x02\x00AB\nC", ""),
    ("GS ( k QR code", b"\x1d(k\x13\x001P0https://x.y/1042", ""),
    ("GS ( L graphics", b"\x1d(L\x06\x000pXYZW", ""),
    ("GS 8 L large graphics", b"\x1d8L\x05\x00\x00\x000pXYZ", ""),
    ("GS k m barcode, NUL-ended", b"\x1dk\x041042\x00", ""),
    ("GS k m n barcode, counted", b"\x1dkI\x06{B1042", ""),
    ("GS V m cut", b"\x1dV\x00", "cut"),
    ("GS V 1 partial cut", b"\x1dV1", "cut"),
    ("GS V 65 n feed and cut", b"\x1dVA3", "cut"),
    ("GS V 66 n feed and cut", b"\x1dVB3", "cut"),
    ("FS & / FS . Chinese mode", b"\x1c&\x1c.", ""),
    ("FS ! n Chinese print mode", b"\x1c!(", ""),
    ("FS - n Chinese underline", b"\x1c-1", ""),
    ("FS C n Kanji code system", b"\x1cC1", ""),
    ("FS W n Chinese quadruple", b"\x1cW1", ""),
    ("FS S n1 n2 Chinese spacing", b"\x1cS00", ""),
    ("FS p n m print NV image", b"\x1cp10", ""),
    ("FS ( A Kanji font", b"\x1c(A\x02\x0001", ""),
    ("FS ( C encoding, one-byte", b"\x1c(C\x02\x0001", ""),
    ("FS 2 user Chinese character", b"\x1c2\xfe\xa1" + b"Z\n" * 36, ""),
    ("FS q define NV image", b"\x1cq\x01\x01\x00\x01\x00NV\nLOGO!", ""),
    ("DLE EOT n status", b"\x10\x04\x01", ""),
    ("DLE ENQ n request", b"\x10\x05\x02", ""),
    ("DLE DC4 1 m t pulse", b"\x10\x14\x01\x00\x01", ""),
    ("DLE DC4 8 clear buffers", b"\x10\x14\x08\x01\x03\x14\x01\x06\x02\x08", ""),
    ("CR and BEL", b"\r\x07", ""),
]


@pytest.mark.parametrize(("what", "command", "shows"), COMMANDS, ids=[c[0] for c in COMMANDS])
def test_a_command_between_two_halves_of_a_word_prints_nothing(
    what: str, command: bytes, shows: str
) -> None:
    tickets = decode_job(b"AB" + command + b"CD\n", "cp437")
    want = {
        "": [("ABCD",)],
        "line": [("AB", "CD")],
        "cut": [("AB",), ("CD",)],
        "clear": [("CD",)],
    }[shows]
    assert printed(tickets) == want, what
    assert sum(t.unknown for t in tickets) == 0, what


def test_esc_d_feeds_its_lines_up_to_eight() -> None:
    assert printed(decode_job(b"A\x1bd\x03B\n")) == [("A", "", "", "B")]
    assert printed(decode_job(b"A\x1bd\xffB\n")) == [("A", *[""] * 7, "B")]


def test_a_tab_moves_to_the_next_stop_of_eight() -> None:
    assert printed(decode_job(b"2\tLaksa\n")) == [("2       Laksa",)]


def test_an_unknown_command_is_skipped_and_counted() -> None:
    (ticket,) = decode_job(b"A\x1b\x01B\x1d\x02C\x1c\x03D\x10\x09E\n")
    assert ticket.lines == ("ABCDE",)
    assert ticket.unknown == 4


# --- Cuts -------------------------------------------------------------------------------------


def test_cuts_split_a_job_into_its_tickets() -> None:
    tickets = decode_job(jobs.SQUARE_TWO.data)
    assert len(tickets) == 2
    assert [t.lines[1] for t in tickets] == ["Table 3", "Table 14"]
    assert all(t.cut for t in tickets)


def test_a_job_without_a_final_cut_still_gives_its_ticket() -> None:
    assert b"\x1dV" not in jobs.TM_STATUS.data and b"\x1bi" not in jobs.TM_STATUS.data
    (ticket,) = decode_job(jobs.TM_STATUS.data, jobs.TM_STATUS.encoding)
    assert ticket.lines == jobs.TM_STATUS.lines
    assert not ticket.cut


def test_text_after_the_last_cut_is_a_ticket_only_if_it_holds_any() -> None:
    assert printed(decode_job(b"A\n\x1dV\x00\n \n\x1bd\x05")) == [("A",)]
    tickets = decode_job(b"A\n\x1dV\x00B")
    assert printed(tickets) == [("A",), ("B",)]
    assert [t.cut for t in tickets] == [True, False]


def test_blank_lines_around_a_ticket_are_paper_but_inside_they_are_lines() -> None:
    assert printed(decode_job(b"\n\n  \nA\n\nB\n\n\n")) == [("A", "", "B")]


# --- Garbled and truncated jobs -----------------------------------------------------------


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_a_garbled_job_gives_text_without_controls_and_counts_its_unknown_commands(
    encoding: str,
) -> None:
    tickets = decode_job(GARBLED.data, encoding)
    assert tickets, "line noise still prints something"
    assert_well_formed(tickets)
    assert sum(t.unknown for t in tickets) > 0


@pytest.mark.parametrize("tail", TRUNCATED.values(), ids=TRUNCATED.keys())
@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_a_command_cut_short_at_the_end_of_a_job_neither_crashes_nor_loops(
    layout: jobs.Layout, tail: bytes
) -> None:
    job = layout.sample
    started = time.perf_counter()
    tickets = decode_job(job.data + tail, job.encoding)
    assert time.perf_counter() - started < 1.0
    assert printed(tickets) == [t.lines for t in job.tickets]


@pytest.mark.parametrize("job", JOBS, ids=lambda j: j.name)
def test_every_prefix_of_a_job_decodes(job: Job) -> None:
    """A connection dropped anywhere in a job: whatever arrived decodes, without a crash."""
    step = max(1, len(job.data) // 120)
    for end in range(0, len(job.data) + 1, step):
        assert_well_formed(decode_job(job.data[:end], job.encoding))


def test_a_huge_job_of_blank_lines_decodes_in_linear_time() -> None:
    """300 000 blank lines before the text: about 0.3 s; stripping them one at a time from
    the front of a list (quadratic) took 10 s."""
    started = time.perf_counter()
    (ticket,) = decode_job(b"\n" * 300_000 + b"Table 12\n")
    assert ticket.lines == ("Table 12",)
    assert time.perf_counter() - started < 3.0


def test_a_long_feed_adds_a_bounded_number_of_lines() -> None:
    (ticket,) = decode_job(b"A" + b"\x1bd\xff" * 10_000 + b"B")
    assert len(ticket.lines) == 8 * 10_000 + 1  # each ESC d 255: the line, and 7 blank ones


# --- Status requests ------------------------------------------------------------------------


@pytest.mark.parametrize("job", EVERY_JOB, ids=lambda j: j.name)
def test_status_replies_answer_each_request_of_a_job(job: Job) -> None:
    assert status_replies(job.data) == b"\x12" * job.status_requests


def test_status_replies_answer_dle_eot_n_online_with_paper() -> None:
    for n in (1, 2, 3, 4):
        assert status_replies(bytes([0x10, 0x04, n])) == b"\x12"  # bits 1 and 4 only
    assert status_replies(jobs.STATUS_REQUEST + b"text" + jobs.PAPER_REQUEST) == b"\x12\x12"
    assert status_replies(b"\x10\x04\x00\x10\x04\x09") == b""
    assert status_replies(b"\x10\x04") == b""  # n has not arrived yet
    assert status_replies(b"Table 12\n\x1dV\x00") == b""


def test_a_status_request_prints_nothing() -> None:
    tickets = decode_job(jobs.TM_STATUS.data, jobs.TM_STATUS.encoding)
    assert tickets[0].lines[0] == "厨房单"


# --- Any bytes at all -------------------------------------------------------------------------

# Pieces that steer random jobs into the decoder's commands: every introducer with each of its
# command letters, and some lengths.
_PIECES = st.sampled_from(
    [
        bytes([intro, op])
        for intro in (0x1B, 0x1D, 0x1C, 0x10)
        for op in b"!-@Eadtiv(k*&VDqp2C\x04\x14"
    ]
    + [b"\n", b"\x00", b"\xff\xff", b"\x02\x00", b"0", b"A", b"\x1c&", b"\x1c."]
)
_JOBS = st.binary(max_size=2000) | st.lists(_PIECES | st.binary(max_size=6), max_size=200).map(
    b"".join
)


@settings(max_examples=250, deadline=500)
@given(data=_JOBS, encoding=st.sampled_from(ENCODINGS))
def test_any_bytes_decode_quickly_into_well_formed_tickets(data: bytes, encoding: str) -> None:
    tickets = decode_job(data, encoding)
    assert_well_formed(tickets)
    assert sum(len(t.lines) for t in tickets) <= 8 * len(data) + 1
    replies = status_replies(data)
    assert replies == b"\x12" * len(replies)
    assert len(replies) <= data.count(b"\x10\x04")


_TEXT = st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=48)


@settings(max_examples=100, deadline=500)
@given(lines=st.lists(_TEXT, min_size=1, max_size=30))
def test_plain_text_prints_as_itself(lines: list[str]) -> None:
    kept = [line.rstrip() for line in lines]
    while kept and not kept[-1].strip():
        kept.pop()
    while kept and not kept[0].strip():
        kept.pop(0)
    data = "\n".join(lines).encode("ascii") + b"\n\x1dV\x00"
    assert printed(decode_job(data)) == ([tuple(kept)] if kept else [])


def test_the_code_pages_a_client_may_name_are_the_decoders() -> None:
    """serveur/wire/till.py cannot import the decoder (the wire imports only the domain), so
    it names the printer's code pages itself: the two lists must stay one."""
    from typing import get_args

    from serveur.till.escpos import ENCODINGS
    from serveur.wire.till import ENCODING_NAMES

    assert get_args(ENCODING_NAMES) == ENCODINGS
