"""Why a session could not be processed, in Spanish, English and Portuguese: the :class:`PipelineError` catalogue.

``PIPELINE_CATALOGUE[code][lang]`` is a :meth:`str.format` template like the ingestion's
(:mod:`app.pipeline.ingestion.messages`, whose :func:`~app.pipeline.ingestion.messages.render` fills both); a
``PipelineError`` may also carry an ingestion code (the provenance checks' ``check.*``).  Parameters may be
fragments ``{"code", "params"}`` rendered in the same language: ``word.*`` (segment, side), and ``warning.*`` — a
quality warning of the estimators (the diagnosis' cause of implausible angles), rendered by
:func:`reports.warning_text.warning_text` from ``reports/translations_warnings.json``.  ``reason`` parameters are an
estimator's English sentence (a ``ValueError`` of the magnetometer fit or a calibration): those few words stay
English inside the translated message.  ``job.*`` are the job runner's own failures (interrupted, disk full,
internal error).  :func:`message_dict` gives the API's ``{"code", "params", "message"}``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from app.pipeline.ingestion.messages import CATALOGUE as INGESTION_CATALOGUE
from app.pipeline.ingestion.messages import LANGUAGES, render

PIPELINE_CATALOGUE: dict[str, dict[str, str]] = {
    "pipeline.no_side": {
        "en": "{file}: the side under study is not known; choose the side (chakamo process --side right|left, or the "
              "patient's side in the web) or add \"side\" to session.json.",
        "es": "{file}: no se conoce el lado estudiado; elija el lado (chakamo process --side right|left, o el lado "
              "del paciente en la web) o añada \"side\" a session.json.",
        "pt": "{file}: não se conhece o lado estudado; escolha o lado (chakamo process --side right|left, ou o lado "
              "do paciente na web) ou acrescente \"side\" ao session.json."},
    "pipeline.side_with_two_knees": {
        "en": "the session holds both knees, each with its own side; --side {side} would give both the same sign: "
              "leave --side out (choose the involved knee with --involved).",
        "es": "la sesión tiene ambas rodillas, cada una con su lado; --side {side} daría a ambas el mismo signo: "
              "quite --side (elija la rodilla afectada con --involved).",
        "pt": "a sessão tem os dois joelhos, cada um com seu lado; --side {side} daria aos dois o mesmo sinal: "
              "retire --side (escolha o joelho afetado com --involved)."},
    "pipeline.side_with_two_knees.web": {
        "en": "the session holds both knees, each with its own side; the side analysed ({side}) would give both the "
              "same sign: process again with \"Side analysed\" left as the patient's side and the knee chosen in "
              "\"Involved knee\" (API: no \"side\" in the process request; \"involved\" instead).",
        "es": "la sesión tiene ambas rodillas, cada una con su lado; el lado analizado ({side}) daría a ambas el "
              "mismo signo: procese de nuevo con \"Lado analizado\" en el lado del paciente y la rodilla elegida en "
              "\"Rodilla afectada\" (API: sin \"side\" en la petición de procesado; \"involved\" en su lugar).",
        "pt": "a sessão tem os dois joelhos, cada um com seu lado; o lado analisado ({side}) daria aos dois o mesmo "
              "sinal: processe de novo com \"Lado analisado\" no lado do paciente e o joelho escolhido em "
              "\"Joelho afetado\" (API: sem \"side\" no pedido de processamento; \"involved\" em seu lugar)."},
    "pipeline.compare_unreadable": {
        "en": "{file}: not the results.json of an earlier analysis ({reason}); give the results.json (or the output "
              "folder) that chakamo process wrote for the earlier session.",
        "es": "{file}: no es el results.json de un análisis anterior ({reason}); indique el results.json (o la "
              "carpeta de salida) que chakamo process escribió para la sesión anterior.",
        "pt": "{file}: não é o results.json de uma análise anterior ({reason}); indique o results.json (ou a pasta "
              "de saída) que o chakamo process escreveu para a sessão anterior."},
    "pipeline.bad_option": {
        "en": "{option} must be one of {allowed}, got {value}; pick one of those.",
        "es": "{option} debe ser uno de {allowed}, no {value}; elija uno de ellos.",
        "pt": "{option} deve ser um de {allowed}, não {value}; escolha um deles."},
    "pipeline.magnetometer_calibration": {
        "en": "{segment} magnetometer calibration ({files}): {reason}",
        "es": "calibración del magnetómetro del {segment} ({files}): {reason}",
        "pt": "calibração do magnetómetro da {segment} ({files}): {reason}"},
    "pipeline.segment_calibration": {
        "en": "{segment} sensor-to-segment calibration ({files}): {reason}",
        "es": "calibración sensor-segmento del {segment} ({files}): {reason}",
        "pt": "calibração sensor-segmento da {segment} ({files}): {reason}"},
    "pipeline.functional_segment_calibration": {
        "en": "sensor-to-segment calibration without the supine posture ({files}): {reason}",
        "es": "calibración sensor-segmento sin la postura supina ({files}): {reason}",
        "pt": "calibração sensor-segmento sem a postura em decúbito dorsal ({files}): {reason}"},
    "pipeline.task_never_straight": {
        "en": "task-only sensor-to-segment calibration ({files}): the stillest straight-knee moment of the task has "
              "the {segment} sensor {angle_deg:.0f}° from upright (more than {max_deg:.0f}°), so the task never held "
              "the knee straight and still; record 2 s standing still with the knee straight at the start of the "
              "task, or add the standing (and lying) recordings",
        "es": "calibración sensor-segmento solo con la tarea ({files}): el momento más quieto con la rodilla "
              "extendida deja el sensor del {segment} a {angle_deg:.0f}° de la vertical (más de {max_deg:.0f}°), así "
              "que la tarea nunca mantuvo la rodilla extendida y quieta; grabe 2 s de pie y quieto con la rodilla "
              "extendida al empezar la tarea, o añada las grabaciones de pie (y tumbado)",
        "pt": "calibração sensor-segmento só com a tarefa ({files}): o momento mais parado com o joelho estendido "
              "deixa o sensor da {segment} a {angle_deg:.0f}° da vertical (mais de {max_deg:.0f}°), portanto a tarefa "
              "nunca manteve o joelho estendido e parado; grave 2 s em pé e parado com o joelho estendido no início "
              "da tarefa, ou acrescente as gravações em pé (e deitado)"},
    "pipeline.functional_calibration": {
        "en": "functional calibration on {thigh_files} and {shank_files}: {reason}",
        "es": "calibración funcional con {thigh_files} y {shank_files}: {reason}",
        "pt": "calibração funcional com {thigh_files} e {shank_files}: {reason}"},
    "pipeline.functional_needs_figure_eight": {
        "en": "the functional calibration needs the magnetometer calibration (figure-eight) recording: without it "
              "the sensors' headings carry the magnetometers' hard iron, which turned the knee's axes by over 10° "
              "in tests; process this session with the static calibration, or record the figure-eight of both "
              "sensors",
        "es": "la calibración funcional necesita la grabación de calibración del magnetómetro (el ocho): sin ella "
              "las orientaciones horizontales de los sensores llevan el hierro duro de los magnetómetros, que giró "
              "los ejes de la rodilla más de 10° en las pruebas; procese esta sesión con la calibración estática o "
              "grabe el ocho de ambos sensores",
        "pt": "a calibração funcional precisa da gravação de calibração do magnetómetro (o oito): sem ela as "
              "orientações horizontais dos sensores carregam o ferro duro dos magnetómetros, que girou os eixos do "
              "joelho mais de 10° nos testes; processe esta sessão com a calibração estática ou grave o oito dos "
              "dois sensores"},
    "pipeline.sensor_turned_round": {
        "en": "{thigh_files} (thigh) and {shank_files} (shank): the thigh and shank sensors do not seem to be worn on "
              "the same side of the leg (one is turned round): the knee's motion fits one sensor turned round far "
              "better than both worn alike; wear both sensors with the same face outwards and their +y axis up the "
              "leg, and record the session again",
        "es": "{thigh_files} (muslo) y {shank_files} (pierna): los sensores del muslo y de la pierna no parecen "
              "llevarse en el mismo lado de la pierna (uno está girado): el movimiento de la rodilla encaja mucho "
              "mejor con un sensor girado que con ambos colocados igual; coloque ambos sensores con la misma cara "
              "hacia fuera y su eje +y hacia arriba a lo largo de la pierna, y grabe de nuevo la sesión",
        "pt": "{thigh_files} (coxa) e {shank_files} (perna): os sensores da coxa e da perna não parecem estar no "
              "mesmo lado da perna (um está virado): o movimento do joelho se ajusta muito melhor a um sensor virado "
              "do que aos dois colocados igual; coloque os dois sensores com a mesma face para fora e o eixo +y para "
              "cima ao longo da perna, e grave a sessão de novo"},
    "pipeline.implausible_angles": {
        "en": "{thigh_files} (thigh) and {shank_files} (shank): {cause}.",
        "es": "{thigh_files} (muslo) y {shank_files} (pierna): {cause}.",
        "pt": "{thigh_files} (coxa) e {shank_files} (perna): {cause}."},
    "pipeline.implausible_unexplained": {
        "en": "{thigh_files} (thigh) and {shank_files} (shank): {cause}; check which recordings belong to which "
              "segment (file names or session.json) and how the sensors were worn.",
        "es": "{thigh_files} (muslo) y {shank_files} (pierna): {cause}; compruebe qué grabaciones pertenecen a cada "
              "segmento (nombres de archivo o session.json) y cómo se llevaban los sensores.",
        "pt": "{thigh_files} (coxa) e {shank_files} (perna): {cause}; verifique que gravações pertencem a cada "
              "segmento (nomes dos ficheiros ou session.json) e como os sensores foram usados."},
    "pipeline.task_analysis": {
        "en": "motor-task analysis of {files}: {reason}",
        "es": "análisis de la tarea motora de {files}: {reason}",
        "pt": "análise da tarefa motora de {files}: {reason}"},
    # ------------------------------------------------------------------ cycles the clinician excluded
    "pipeline.exclude_rejected_cycle": {
        "en": "cycle {cycle} cannot be excluded: the pipeline already left it out (its reason stands); choose among the "
              "cycles it measured",
        "es": "no se puede excluir el ciclo {cycle}: el proceso ya lo dejó fuera (se mantiene su motivo); elija entre "
              "los ciclos que midió",
        "pt": "não é possível excluir o ciclo {cycle}: o processamento já o deixou de fora (mantém-se o seu motivo); "
              "escolha entre os ciclos que mediu"},
    "pipeline.exclude_unknown_cycle": {
        "en": "cycle {cycle} cannot be excluded: {detected} cycles were detected; choose among cycles 1 to {detected}",
        "es": "no se puede excluir el ciclo {cycle}: se detectaron {detected} ciclos; elija entre los ciclos 1 y "
              "{detected}",
        "pt": "não é possível excluir o ciclo {cycle}: foram detetados {detected} ciclos; escolha entre os ciclos 1 "
              "e {detected}"},
    "pipeline.exclude_every_cycle": {
        "en": "excluding {excluded} cycles leaves none of the {detected} detected in the statistics; keep at least "
              "one cycle",
        "es": "al excluir {excluded} ciclos no queda ninguno de los {detected} detectados en la estadística; "
              "conserve al menos un ciclo",
        "pt": "ao excluir {excluded} ciclos não resta nenhum dos {detected} detetados na estatística; mantenha pelo "
              "menos um ciclo"},
    "pipeline.exclude_other_knee": {
        "en": "cycle {cycle} is excluded on the {knee} knee, which this session does not hold; name the session's "
              "knee (or no knee when it holds one)",
        "es": "el ciclo {cycle} se excluye en la rodilla {knee}, que esta sesión no contiene; indique la rodilla de "
              "la sesión (o ninguna si solo tiene una)",
        "pt": "o ciclo {cycle} é excluído no joelho {knee}, que esta sessão não contém; indique o joelho da sessão "
              "(ou nenhum se ela tiver só um)"},
    "pipeline.exclude_no_knee": {
        "en": "the session holds both knees: say on which knee cycle {cycle} is excluded (e.g. right:{cycle})",
        "es": "la sesión contiene ambas rodillas: indique en qué rodilla se excluye el ciclo {cycle} (p. ej. "
              "right:{cycle})",
        "pt": "a sessão contém os dois joelhos: indique em que joelho o ciclo {cycle} é excluído (p. ex. "
              "right:{cycle})"},
    # ------------------------------------------------------------------ the job runner's own failures
    "job.interrupted": {
        "en": "processing was interrupted {attempts} times; check the server's and the workers' memory and logs, "
              "then process the session again",
        "es": "el procesamiento se interrumpió {attempts} veces; revise la memoria y los registros del servidor y "
              "de los trabajadores, y procese de nuevo la sesión",
        "pt": "o processamento foi interrompido {attempts} vezes; verifique a memória e os registos do servidor e "
              "dos trabalhadores, e processe de novo a sessão"},
    "job.disk_full": {
        "en": "The server's disk is full, so the reports could not be stored and none was recorded. Ask your ChakaMo "
              "administrator to free space, then process the session again.",
        "es": "El disco del servidor está lleno, así que no se pudieron guardar los informes y no se registró "
              "ninguno. Pida al administrador de ChakaMo que libere espacio y procese de nuevo la sesión.",
        "pt": "O disco do servidor está cheio, por isso os relatórios não puderam ser guardados e nenhum foi "
              "registado. Peça ao administrador do ChakaMo que liberte espaço e processe de novo a sessão."},
    "job.internal": {
        "en": "An internal error stopped the processing (reference {ref}); try again, and if it happens again give "
              "the reference to your ChakaMo administrator.",
        "es": "Un error interno detuvo el procesamiento (referencia {ref}); inténtelo de nuevo y, si vuelve a pasar, "
              "dé la referencia al administrador de ChakaMo.",
        "pt": "Um erro interno parou o processamento (referência {ref}); tente de novo e, se voltar a acontecer, dê "
              "a referência ao administrador do ChakaMo."},
}

__all__ = ["LANGUAGES", "PIPELINE_CATALOGUE", "known", "message_dict", "render_message"]


def known(code: str) -> bool:
    """True when ``code`` has a text in this catalogue or the ingestion's."""
    return code in PIPELINE_CATALOGUE or code in INGESTION_CATALOGUE


def _fragments(value: Any, lang: str) -> Any:
    """``warning.*`` fragments rendered by the reports' warning catalogue; everything else as it is."""
    if isinstance(value, Mapping) and str(value.get("code", "")).startswith("warning."):
        from reports.warning_text import warning_text

        w = {"code": value["code"].removeprefix("warning."), "params": value.get("params", {}),
             "message": value.get("message", "")}
        return warning_text(w, lang)[0]
    return value


def render_message(code: str, params: Mapping[str, Any], lang: str = "en") -> str:
    """The message ``code`` (this catalogue or the ingestion's) in ``lang``, filled from ``params``."""
    values = {k: _fragments(v, lang) for k, v in params.items()}
    if code in PIPELINE_CATALOGUE:
        return render(code, values, lang, catalogue=PIPELINE_CATALOGUE)
    return render(code, values, lang)


def message_dict(code: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """``{"code", "params", "message": {lang: text}}`` (API answers, job records)."""
    return {"code": code, "params": dict(params),
            "message": {lang: render_message(code, params, lang) for lang in LANGUAGES}}
