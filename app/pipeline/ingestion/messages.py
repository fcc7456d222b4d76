"""Every message of the ingestion layer a user can cause, in Spanish, English and Portuguese, from one table.

``CATALOGUE[code][lang]`` is a :meth:`str.format` template; :func:`render` fills it from the message's
``params`` (``{file}`` names the file or folder, a message always ends saying what to do).  A parameter may
itself be a fragment ``{"code": ..., "params": {...}}`` or a list of fragments (hints, words): it is rendered
in the same language, a list joined by spaces.  Codes are stable identifiers: the API and the job records
carry ``{"code", "params"}`` and render them in the reader's language.

Families: ``file.*``, ``cell.*``, ``stamp.*``, ``stream.*`` (any table), ``metabase.*``, ``generic.*``,
``xlsx.*``, ``xsens.*``, ``opal.*``, ``shimmer.*``, ``phone.*``, ``phyphox.*`` (one format), ``zip.*`` (a phone app's zip), ``split.*``, ``unit.*``, ``rate.*``,
``align.*``, ``recording.*``, ``session.*``, ``manifest.*``; ``note.*`` the notes (``Note.of(variant)``),
``check.*`` the provenance checks (:mod:`.provenance`), ``hint.*`` / ``word.*`` fragments.

Suggestions are things a user can do both from the CLI and from the web app (export again, rename, edit
``session.json``, record again); ``chakamo process --any-rate`` is named only where it would make the file
load (acc and gyro at one rate, magnetometer within range), and only as the command line's option.
"""

from __future__ import annotations

import string
from typing import Any, Mapping

LANGUAGES = ("es", "en", "pt")

CATALOGUE: dict[str, dict[str, str]] = {
    # ------------------------------------------------------------------------------------------- files
    "file.unreadable": {
        "en": "{file}: cannot be read ({reason}); check that the file exists and is readable, or copy it again.",
        "es": "{file}: no se puede leer ({reason}); compruebe que el archivo existe y se puede leer, o cópielo de nuevo.",
        "pt": "{file}: não pode ser lido ({reason}); verifique se o ficheiro existe e pode ser lido, ou copie-o de novo."},
    "file.nul_bytes": {
        "en": "{file}: the file contains NUL bytes (saved as UTF-16/UTF-32 'Unicode text', or damaged); save it "
              "again as a UTF-8 (or plain) CSV, or export the recording again.",
        "es": "{file}: el archivo contiene bytes NUL (guardado como 'texto Unicode' UTF-16/UTF-32, o dañado); "
              "guárdelo de nuevo como CSV UTF-8 (o simple), o exporte de nuevo la grabación.",
        "pt": "{file}: o ficheiro contém bytes NUL (guardado como 'texto Unicode' UTF-16/UTF-32, ou danificado); "
              "guarde-o de novo como CSV UTF-8 (ou simples), ou exporte a gravação de novo."},
    "file.not_text": {
        "en": "{file}: not a text CSV file ({reason}); export it again as CSV.",
        "es": "{file}: no es un archivo CSV de texto ({reason}); expórtelo de nuevo como CSV.",
        "pt": "{file}: não é um ficheiro CSV de texto ({reason}); exporte-o de novo como CSV."},
    "file.damaged_csv": {
        "en": "{file}: not a readable CSV file ({reason}); the file is damaged — export the recording again.",
        "es": "{file}: no es un archivo CSV legible ({reason}); el archivo está dañado: exporte de nuevo la grabación.",
        "pt": "{file}: não é um ficheiro CSV legível ({reason}); o ficheiro está danificado: exporte a gravação de novo."},
    "file.empty": {
        "en": "{file}: the file is empty; export the recording again.",
        "es": "{file}: el archivo está vacío; exporte de nuevo la grabación.",
        "pt": "{file}: o ficheiro está vazio; exporte a gravação de novo."},
    "file.header_only": {
        "en": "{file}: the file has a header but no data rows; export the recording again.",
        "es": "{file}: el archivo tiene encabezado pero ninguna fila de datos; exporte de nuevo la grabación.",
        "pt": "{file}: o ficheiro tem cabeçalho mas nenhuma linha de dados; exporte a gravação de novo."},
    "file.ragged_row": {
        "en": "{file}: row {row} has {cells} cells but the header has {header_cells}; the file is damaged or has a "
              "stray separator — export it again.",
        "es": "{file}: la fila {row} tiene {cells} celdas pero el encabezado tiene {header_cells}; el archivo está "
              "dañado o tiene un separador de más: expórtelo de nuevo.",
        "pt": "{file}: a linha {row} tem {cells} células mas o cabeçalho tem {header_cells}; o ficheiro está "
              "danificado ou tem um separador a mais: exporte-o de novo."},
    "file.not_found": {
        "en": "{file}: file not found; check the name (or the session.json entry).",
        "es": "{file}: archivo no encontrado; compruebe el nombre (o la entrada de session.json).",
        "pt": "{file}: ficheiro não encontrado; verifique o nome (ou a entrada do session.json)."},
    "file.axes_units_differ": {
        "en": "{file}: the three axes declare different units ({units}); fix the header so they declare one.",
        "es": "{file}: los tres ejes declaran unidades distintas ({units}); corrija el encabezado para que declaren una.",
        "pt": "{file}: os três eixos declaram unidades diferentes ({units}); corrija o cabeçalho para que declarem uma."},
    "cell.not_number": {
        "en": "{file}: row {row}, column '{column}' holds '{cell}', which is not a number; fix or delete that row.",
        "es": "{file}: la fila {row}, columna '{column}', contiene '{cell}', que no es un número; corrija o borre esa fila.",
        "pt": "{file}: a linha {row}, coluna '{column}', contém '{cell}', que não é um número; corrija ou apague essa linha."},
    "cell.infinite": {
        "en": "{file}: row {row}, column '{column}' is infinite; fix or delete that row.",
        "es": "{file}: la fila {row}, columna '{column}', es infinita; corrija o borre esa fila.",
        "pt": "{file}: a linha {row}, coluna '{column}', é infinita; corrija ou apague essa linha."},
    "cell.huge": {
        "en": "{file}: row {row}, column '{column}' holds {value}, beyond any time stamp or reading; fix or delete "
              "that row.",
        "es": "{file}: la fila {row}, columna '{column}', contiene {value}, más que cualquier marca de tiempo o "
              "lectura; corrija o borre esa fila.",
        "pt": "{file}: a linha {row}, coluna '{column}', contém {value}, além de qualquer marca de tempo ou "
              "leitura; corrija ou apague essa linha."},
    "stamp.missing": {
        "en": "{file}: row {row} has no time stamp in '{column}'; fix or delete that row.",
        "es": "{file}: la fila {row} no tiene marca de tiempo en '{column}'; corrija o borre esa fila.",
        "pt": "{file}: a linha {row} não tem marca de tempo em '{column}'; corrija ou apague essa linha."},
    "stamp.repeats": {
        "en": "{file}: rows {row} and {row2}: the time stamp in '{column}' repeats at {at} with other values (two "
              "samples at one instant). Export the recording again, or delete one of the two rows.",
        "es": "{file}: filas {row} y {row2}: la marca de tiempo de '{column}' se repite en {at} con otros valores "
              "(dos muestras en un instante). Exporte de nuevo la grabación, o borre una de las dos filas.",
        "pt": "{file}: linhas {row} e {row2}: a marca de tempo de '{column}' se repete em {at} com outros valores "
              "(duas amostras num instante). Exporte a gravação de novo, ou apague uma das duas linhas."},
    "stamp.goes_back": {
        "en": "{file}: rows {row} and {row2}: the time stamp in '{column}' goes back in time at {at} (out-of-order "
              "rows or a clock reset). Export the recording again, or put the rows back in time order.",
        "es": "{file}: filas {row} y {row2}: la marca de tiempo de '{column}' retrocede en {at} (filas "
              "desordenadas o un reinicio del reloj). Exporte de nuevo la grabación, u ordene las filas por tiempo.",
        "pt": "{file}: linhas {row} e {row2}: a marca de tempo de '{column}' volta atrás em {at} (linhas fora de "
              "ordem ou um reinício do relógio). Exporte a gravação de novo, ou ordene as linhas por tempo."},
    "stream.too_short": {
        "en": "{file}: only {samples} samples ({seconds:.2f} s); the recording is too short (at least {min_s:g} s) "
              "— record again.",
        "es": "{file}: solo {samples} muestras ({seconds:.2f} s); la grabación es demasiado corta (al menos "
              "{min_s:g} s): grabe de nuevo.",
        "pt": "{file}: apenas {samples} amostras ({seconds:.2f} s); a gravação é curta demais (pelo menos "
              "{min_s:g} s): grave de novo."},
    "stream.all_empty": {
        "en": "{file}: every sample is empty; export the recording again.",
        "es": "{file}: todas las muestras están vacías; exporte de nuevo la grabación.",
        "pt": "{file}: todas as amostras estão vazias; exporte a gravação de novo."},
    "stream.no_valid_sample": {
        "en": "{file}: no valid {stream} sample; export the recording again.",
        "es": "{file}: ninguna muestra válida de {stream}; exporte de nuevo la grabación.",
        "pt": "{file}: nenhuma amostra válida de {stream}; exporte a gravação de novo."},
    # ---------------------------------------------------------------------------------------- MetaBase
    "metabase.not_a_stream": {
        "en": "{file}: not a MetaBase stream file: the header '{header}' lacks 'epoch (ms)' or 'elapsed (s)' and "
              "'x-axis/y-axis/z-axis (unit)' columns; export the stream again from MetaBase (or rename the file "
              "if it is not a stream export).",
        "es": "{file}: no es un archivo de flujo de MetaBase: al encabezado '{header}' le faltan las columnas "
              "'epoch (ms)' o 'elapsed (s)' y 'x-axis/y-axis/z-axis (unidad)'; exporte de nuevo el flujo desde "
              "MetaBase (o renombre el archivo si no es una exportación de flujo).",
        "pt": "{file}: não é um ficheiro de fluxo do MetaBase: ao cabeçalho '{header}' faltam as colunas "
              "'epoch (ms)' ou 'elapsed (s)' e 'x-axis/y-axis/z-axis (unidade)'; exporte o fluxo de novo do "
              "MetaBase (ou renomeie o ficheiro se não for uma exportação de fluxo)."},
    "metabase.excel_epoch_no_name": {
        "en": "{file}: the '{column}' stamps were rounded by a spreadsheet (e.g. 1.63552E+12) and the file name "
              "no longer carries MetaBase's start time to rebuild them; give the file its MetaBase name again, or "
              "export the recording again.",
        "es": "{file}: las marcas '{column}' fueron redondeadas por una hoja de cálculo (p. ej. 1,63552E+12) y el "
              "nombre del archivo ya no lleva la hora de inicio de MetaBase para reconstruirlas; devuelva al "
              "archivo su nombre de MetaBase, o exporte de nuevo la grabación.",
        "pt": "{file}: as marcas '{column}' foram arredondadas por uma folha de cálculo (p. ex. 1,63552E+12) e o nome do "
              "ficheiro já não traz a hora de início do MetaBase para reconstruí-las; devolva ao ficheiro o seu nome "
              "do MetaBase, ou exporte a gravação de novo."},
    "metabase.several_recordings": {
        "en": "{file}: these files belong to {count} different MetaBase recordings ({labels}); list one "
              "recording's three files together.",
        "es": "{file}: estos archivos pertenecen a {count} grabaciones distintas de MetaBase ({labels}); liste "
              "juntos los tres archivos de una grabación.",
        "pt": "{file}: estes ficheiros pertencem a {count} gravações diferentes do MetaBase ({labels}); liste "
              "juntos os três ficheiros de uma gravação."},
    "metabase.stream_missing": {
        "en": "{file}: recording '{label}' of sensor {sensor} has no {streams} file; export every stream from "
              "MetaBase. {hint}",
        "es": "{file}: la grabación '{label}' del sensor {sensor} no tiene archivo {streams}; exporte todos los "
              "flujos desde MetaBase. {hint}",
        "pt": "{file}: a gravação '{label}' do sensor {sensor} não tem ficheiro {streams}; exporte todos os "
              "fluxos do MetaBase. {hint}"},
    "metabase.stream_twice": {
        "en": "{file} and {other} are both the {stream} of recording '{label}' on sensor {sensor}; keep only one "
              "of them (or rename the label).",
        "es": "{file} y {other} son ambos el {stream} de la grabación '{label}' del sensor {sensor}; conserve "
              "solo uno (o cambie la etiqueta).",
        "pt": "{file} e {other} são ambos o {stream} da gravação '{label}' do sensor {sensor}; mantenha apenas "
              "um (ou mude o rótulo)."},
    # ------------------------------------------------------------------------------------------ generic
    "generic.column_missing": {
        "en": "{file}: no column {columns} in the header; a generic CSV needs time, acc_x..z, gyr_x..z, mag_x..z, "
              "each with its unit, e.g. 'acc_x (g)': add the missing column(s) or export the file again.",
        "es": "{file}: no hay columna {columns} en el encabezado; un CSV genérico necesita time, acc_x..z, "
              "gyr_x..z, mag_x..z, cada una con su unidad, p. ej. 'acc_x (g)': añada la(s) columna(s) que faltan "
              "o exporte de nuevo el archivo.",
        "pt": "{file}: não há coluna {columns} no cabeçalho; um CSV genérico precisa de time, acc_x..z, gyr_x..z, "
              "mag_x..z, cada uma com a sua unidade, p. ex. 'acc_x (g)': adicione a(s) coluna(s) que faltam ou "
              "exporte o ficheiro de novo."},
    "generic.no_time": {
        "en": "{file}: no time column; add 'time (s)' (or 'epoch (ms)') as the first column.",
        "es": "{file}: no hay columna de tiempo; añada 'time (s)' (o 'epoch (ms)') como primera columna.",
        "pt": "{file}: não há coluna de tempo; adicione 'time (s)' (ou 'epoch (ms)') como primeira coluna."},
    "generic.units_differ": {
        "en": "{file}: columns {columns} must declare one unit; give each the same unit in the header, e.g. "
              "'{example}'.",
        "es": "{file}: las columnas {columns} deben declarar una sola unidad; dé a cada una la misma unidad en el "
              "encabezado, p. ej. '{example}'.",
        "pt": "{file}: as colunas {columns} devem declarar uma só unidade; dê a cada uma a mesma unidade no "
              "cabeçalho, p. ex. '{example}'."},
    "generic.unit_unknown": {
        "en": "{file}: unit ({unit}) is not one ChakaMo knows; correct the header to s/ms, g/mg/m_s2, "
              "deg/s/rad/s, T/mT/uT/nT or normalised.",
        "es": "{file}: la unidad ({unit}) no es una que ChakaMo conozca; corrija el encabezado a s/ms, g/mg/m_s2, "
              "deg/s/rad/s, T/mT/uT/nT o normalised.",
        "pt": "{file}: a unidade ({unit}) não é uma que o ChakaMo conheça; corrija o cabeçalho para s/ms, "
              "g/mg/m_s2, deg/s/rad/s, T/mT/uT/nT ou normalised."},
    "generic.stream_empty": {
        "en": "{file}: the {stream} columns are empty; export the recording again.",
        "es": "{file}: las columnas de {stream} están vacías; exporte de nuevo la grabación.",
        "pt": "{file}: as colunas de {stream} estão vazias; exporte a gravação de novo."},
    # ---------------------------------------------------------------------------- Xsens, Shimmer, APDM
    "xsens.columns_missing": {
        "en": "{file}: an MT Manager export needs the columns {columns}; export it again from MT Manager with "
              "calibrated acceleration (Acc, not FreeAcc), rate of turn and magnetic field.",
        "es": "{file}: una exportación de MT Manager necesita las columnas {columns}; expórtela de nuevo desde MT "
              "Manager con aceleración calibrada (Acc, no FreeAcc), velocidad angular y campo magnético.",
        "pt": "{file}: uma exportação do MT Manager precisa das colunas {columns}; exporte-a de novo do MT "
              "Manager com aceleração calibrada (Acc, não FreeAcc), velocidade angular e campo magnético."},
    "xsens.no_time": {
        "en": "{file}: no time in this MT Manager export (no valid UTC_*, SampleTimeFine, or PacketCounter with "
              "an update rate); export it again with SampleTimeFine.",
        "es": "{file}: esta exportación de MT Manager no tiene tiempo (ni UTC_* válido, ni SampleTimeFine, ni "
              "PacketCounter con frecuencia); expórtela de nuevo con SampleTimeFine.",
        "pt": "{file}: esta exportação do MT Manager não tem tempo (nem UTC_* válido, nem SampleTimeFine, nem "
              "PacketCounter com frequência); exporte-a de novo com SampleTimeFine."},
    "shimmer.no_units_row": {
        "en": "{file}: a Consensys export needs its units row (ms, m/(s^2), deg/s, local_flux) under the column "
              "names; export it again from Consensys with calibrated (CAL) data.",
        "es": "{file}: una exportación de Consensys necesita su fila de unidades (ms, m/(s^2), deg/s, local_flux) "
              "bajo los nombres de columna; expórtela de nuevo desde Consensys con datos calibrados (CAL).",
        "pt": "{file}: uma exportação do Consensys precisa da sua linha de unidades (ms, m/(s^2), deg/s, "
              "local_flux) sob os nomes das colunas; exporte-a de novo do Consensys com dados calibrados (CAL)."},
    "shimmer.columns_missing": {
        "en": "{file}: the Consensys export lacks {columns} (calibrated, _CAL); export it again with the "
              "accelerometer, gyroscope, magnetometer and Unix time stamps enabled.",
        "es": "{file}: a la exportación de Consensys le falta {columns} (calibrado, _CAL); expórtela de nuevo con "
              "acelerómetro, giroscopio, magnetómetro y marcas de tiempo Unix activados.",
        "pt": "{file}: à exportação do Consensys falta {columns} (calibrado, _CAL); exporte-a de novo com "
              "acelerómetro, giroscópio, magnetómetro e marcas de tempo Unix ativados."},
    "shimmer.unit_unknown": {
        "en": "{file}: unit '{unit}' of column {column} is not one ChakaMo knows for a Consensys export; export "
              "it again with calibrated (CAL) data.",
        "es": "{file}: la unidad '{unit}' de la columna {column} no es una que ChakaMo conozca para una "
              "exportación de Consensys; expórtela de nuevo con datos calibrados (CAL).",
        "pt": "{file}: a unidade '{unit}' da coluna {column} não é uma que o ChakaMo conheça para uma exportação "
              "do Consensys; exporte-a de novo com dados calibrados (CAL)."},
    "opal.no_h5py": {
        "en": "reading APDM .h5 files needs the 'h5py' package: install ChakaMo again (pip install -e .).",
        "es": "leer archivos .h5 de APDM necesita el paquete 'h5py': instale ChakaMo de nuevo (pip install -e .).",
        "pt": "ler ficheiros .h5 da APDM precisa do pacote 'h5py': instale o ChakaMo de novo (pip install -e .)."},
    "opal.cannot_open": {
        "en": "{file}: cannot be opened as an HDF5 file ({reason}); copy it again or export it again from "
              "Mobility Lab / Motion Studio.",
        "es": "{file}: no se puede abrir como archivo HDF5 ({reason}); cópielo de nuevo o expórtelo de nuevo "
              "desde Mobility Lab / Motion Studio.",
        "pt": "{file}: não pode ser aberto como ficheiro HDF5 ({reason}); copie-o de novo ou exporte-o de novo do "
              "Mobility Lab / Motion Studio."},
    "opal.not_apdm": {
        "en": "{file}: an HDF5 file that is not an APDM Opal recording (no /Sensors group; it holds {datasets}). "
              "ChakaMo reads HDF5 only as Mobility Lab / Motion Studio export it: write the recording's "
              "accelerometer, gyroscope and magnetometer as a generic CSV (a header with units, e.g. acc_x (m/s^2)) "
              "and upload that.",
        "es": "{file}: un archivo HDF5 que no es una grabación de APDM Opal (sin grupo /Sensors; contiene "
              "{datasets}). ChakaMo lee HDF5 solo como lo exportan Mobility Lab / Motion Studio: escriba el "
              "acelerómetro, el giroscopio y el magnetómetro de la grabación como un CSV genérico (una cabecera con "
              "unidades, p. ej. acc_x (m/s^2)) y súbalo.",
        "pt": "{file}: um ficheiro HDF5 que não é uma gravação APDM Opal (sem grupo /Sensors; contém {datasets}). "
              "O ChakaMo lê HDF5 apenas como o Mobility Lab / Motion Studio o exportam: escreva o acelerómetro, o "
              "giroscópio e o magnetómetro da gravação como um CSV genérico (um cabeçalho com unidades, p. ex. "
              "acc_x (m/s^2)) e envie-o."},
    "opal.not_v5": {
        "en": "{file}: not an APDM file of format version 5 (no /Sensors group); export it again from Mobility "
              "Lab / Motion Studio in the current HDF5 format.",
        "es": "{file}: no es un archivo APDM de la versión de formato 5 (sin grupo /Sensors); expórtelo de nuevo "
              "desde Mobility Lab / Motion Studio en el formato HDF5 actual.",
        "pt": "{file}: não é um ficheiro APDM da versão de formato 5 (sem grupo /Sensors); exporte-o de novo do "
              "Mobility Lab / Motion Studio no formato HDF5 atual."},
    "opal.which_sensor": {
        "en": "{file}: the file holds the sensors {sensors}; name the one of each recording in session.json "
              "(\"sensor\" in its recordings entry).",
        "es": "{file}: el archivo contiene los sensores {sensors}; indique el de cada grabación en session.json "
              "(\"sensor\" en su entrada de recordings).",
        "pt": "{file}: o ficheiro contém os sensores {sensors}; indique o de cada gravação no session.json "
              "(\"sensor\" na sua entrada de recordings)."},
    "opal.no_such_sensor": {
        "en": "{file}: no sensor '{sensor}' in the file (it holds {sensors}); correct \"sensor\" in session.json.",
        "es": "{file}: no hay sensor '{sensor}' en el archivo (contiene {sensors}); corrija \"sensor\" en "
              "session.json.",
        "pt": "{file}: não há sensor '{sensor}' no ficheiro (contém {sensors}); corrija \"sensor\" no "
              "session.json."},
    "opal.datasets_missing": {
        "en": "{file}: sensor {sensor} has no {datasets} data; export the recording again with accelerometer, "
              "gyroscope and magnetometer.",
        "es": "{file}: el sensor {sensor} no tiene datos de {datasets}; exporte de nuevo la grabación con "
              "acelerómetro, giroscopio y magnetómetro.",
        "pt": "{file}: o sensor {sensor} não tem dados de {datasets}; exporte a gravação de novo com "
              "acelerómetro, giroscópio e magnetómetro."},
    "opal.bad_shape": {
        "en": "{file}: {dataset} has shape {shape}, expected {expected}; the file is damaged — export it again.",
        "es": "{file}: {dataset} tiene forma {shape}, se esperaba {expected}; el archivo está dañado: expórtelo de "
              "nuevo.",
        "pt": "{file}: {dataset} tem forma {shape}, esperava-se {expected}; o ficheiro está danificado: exporte-o de "
              "novo."},
    "opal.too_large": {
        "en": "{file}: {dataset} declares {shape} entries (at most {limit}: two hours at 200 Hz, 64 sensors); "
              "export shorter recordings from Mobility Lab / Motion Studio.",
        "es": "{file}: {dataset} declara {shape} entradas (como máximo {limit}: dos horas a 200 Hz, 64 sensores); "
              "exporte grabaciones más cortas desde Mobility Lab / Motion Studio.",
        "pt": "{file}: {dataset} declara {shape} entradas (no máximo {limit}: duas horas a 200 Hz, 64 sensores); "
              "exporte gravações mais curtas do Mobility Lab / Motion Studio."},
    "phyphox.linear_acceleration": {
        "en": "{file}: {member} holds '{column}', phyphox's acceleration without gravity, which the sensor "
              "calibration needs; record with the \"Acceleration with g\" experiment and export it again.",
        "es": "{file}: {member} contiene '{column}', la aceleración sin gravedad de phyphox, que la calibración "
              "de los sensores necesita; grabe con el experimento \"Aceleración con g\" y expórtelo de nuevo.",
        "pt": "{file}: {member} contém '{column}', a aceleração sem gravidade do phyphox, de que a calibração "
              "dos sensores precisa; grave com a experiência \"Aceleração com g\" e exporte-a de novo."},
    "phyphox.axes_missing": {
        "en": "{file}: {member} has {sensor} without its {axes} column(s); export the experiment again with all "
              "three axes.",
        "es": "{file}: {member} tiene {sensor} sin su(s) columna(s) {axes}; exporte de nuevo el experimento con "
              "los tres ejes.",
        "pt": "{file}: {member} tem {sensor} sem a(s) coluna(s) {axes}; exporte de novo a experiência com os "
              "três eixos."},
    "phyphox.unit_unknown": {
        "en": "{file}: {member}: column '{column}' is in '{unit}', a unit ChakaMo does not know; export it again "
              "from phyphox without editing its header.",
        "es": "{file}: {member}: la columna '{column}' está en '{unit}', una unidad que ChakaMo no conoce; "
              "expórtela de nuevo desde phyphox sin editar su cabecera.",
        "pt": "{file}: {member}: a coluna '{column}' está em '{unit}', uma unidade que o ChakaMo não conhece; "
              "exporte-a de novo do phyphox sem editar o cabeçalho."},
    "phyphox.sensor_twice": {
        "en": "{file}: {sensor} appears twice in this recording's phyphox exports; list one export per sensor "
              "for the recording (session.json files).",
        "es": "{file}: {sensor} aparece dos veces en las exportaciones phyphox de esta grabación; liste una "
              "exportación por sensor para la grabación (files de session.json).",
        "pt": "{file}: {sensor} aparece duas vezes nas exportações phyphox desta gravação; liste uma exportação "
              "por sensor para a gravação (files do session.json)."},
    "phyphox.sensors_missing": {
        "en": "{file}: the phyphox export lacks {sensors}; a recording needs acceleration with g, gyroscope and "
              "magnetometer: record them in one experiment, or list the three exports together in session.json "
              "(one recording's files).",
        "es": "{file}: a la exportación phyphox le falta {sensors}; una grabación necesita aceleración con g, "
              "giroscopio y magnetómetro: grábelos en un mismo experimento, o liste las tres exportaciones juntas "
              "en session.json (los files de una grabación).",
        "pt": "{file}: à exportação phyphox falta {sensors}; uma gravação precisa de aceleração com g, giroscópio "
              "e magnetómetro: grave-os numa mesma experiência, ou liste as três exportações juntas no "
              "session.json (os files de uma gravação)."},
    "phone.not_a_zip": {
        "en": "{file}: not a readable zip file ({reason}); export the recording again from Sensor Logger (zip).",
        "es": "{file}: no es un archivo zip legible ({reason}); exporte de nuevo la grabación desde Sensor Logger "
              "(zip).",
        "pt": "{file}: não é um ficheiro zip legível ({reason}); exporte a gravação de novo do Sensor Logger (zip)."},
    "phone.member_unreadable": {
        "en": "{file}: {member} cannot be read ({reason}); export the recording again from Sensor Logger.",
        "es": "{file}: no se puede leer {member} ({reason}); exporte de nuevo la grabación desde Sensor Logger.",
        "pt": "{file}: não é possível ler {member} ({reason}); exporte a gravação de novo do Sensor Logger."},
    "phone.files_missing": {
        "en": "{file}: the Sensor Logger export lacks {files}; record again with the accelerometer, gravity, "
              "gyroscope and magnetometer enabled, and export as zip.",
        "es": "{file}: a la exportación de Sensor Logger le falta {files}; grabe de nuevo con acelerómetro, "
              "gravedad, giroscopio y magnetómetro activados, y exporte como zip.",
        "pt": "{file}: à exportação do Sensor Logger falta {files}; grave de novo com acelerómetro, gravidade, "
              "giroscópio e magnetómetro ativados, e exporte como zip."},
    "phone.columns_missing": {
        "en": "{file}: {member} has no column {columns}; export the recording again from Sensor Logger.",
        "es": "{file}: {member} no tiene la columna {columns}; exporte de nuevo la grabación desde Sensor Logger.",
        "pt": "{file}: {member} não tem a coluna {columns}; exporte a gravação de novo do Sensor Logger."},
    # -------------------------------------------------------------------------------------------- Excel
    "xlsx.no_openpyxl": {
        "en": "reading .xlsx files needs the 'openpyxl' package: install ChakaMo again (pip install -e .), or "
              "save the workbook as CSV.",
        "es": "leer archivos .xlsx necesita el paquete 'openpyxl': instale ChakaMo de nuevo (pip install -e .), "
              "o guarde el libro como CSV.",
        "pt": "ler ficheiros .xlsx precisa do pacote 'openpyxl': instale o ChakaMo de novo (pip install -e .), ou "
              "guarde o livro como CSV."},
    "xlsx.cannot_open": {
        "en": "{file}: cannot be opened as an Excel workbook ({reason}); save it again from Excel as .xlsx.",
        "es": "{file}: no se puede abrir como libro de Excel ({reason}); guárdelo de nuevo desde Excel como .xlsx.",
        "pt": "{file}: não pode ser aberto como livro do Excel ({reason}); guarde-o de novo no Excel "
              "como .xlsx."},
    "xlsx.no_such_sheet": {
        "en": "{file}: no sheet named '{sheet}'; the sheets are {sheets} — correct \"sheet\" in session.json.",
        "es": "{file}: no hay ninguna hoja llamada '{sheet}'; las hojas son {sheets}: corrija \"sheet\" en "
              "session.json.",
        "pt": "{file}: não há folha chamada '{sheet}'; as folhas são {sheets}: corrija \"sheet\" no "
              "session.json."},
    "xlsx.no_layout_sheet": {
        "en": "{file}: none of its sheets has the thesis layout (Fig. 8.6: A elapsed, B–D acc, E–G gyro, H "
              "elapsed, I–K mag){detail}. Keep one such sheet, or name it in session.json (\"sheet\").",
        "es": "{file}: ninguna de sus hojas tiene el formato de la tesis (Fig. 8.6: A elapsed, B–D acc, E–G gyro, "
              "H elapsed, I–K mag){detail}. Conserve una hoja así, o nómbrela en session.json (\"sheet\").",
        "pt": "{file}: nenhuma das suas folhas de cálculo tem o formato da tese (Fig. 8.6: A elapsed, B–D acc, E–G gyro, "
              "H elapsed, I–K mag){detail}. Mantenha uma folha de cálculo assim, ou nomeie-a no session.json (\"sheet\")."},
    "xlsx.several_layout_sheets": {
        "en": "{file}: several sheets ({sheets}) have the thesis layout (Fig. 8.6){detail}. Keep one such sheet, "
              "or name it in session.json (\"sheet\").",
        "es": "{file}: varias hojas ({sheets}) tienen el formato de la tesis (Fig. 8.6){detail}. Conserve una "
              "sola, o nómbrela en session.json (\"sheet\").",
        "pt": "{file}: várias folhas de cálculo ({sheets}) têm o formato da tese (Fig. 8.6){detail}. Mantenha só uma, "
              "ou nomeie-a no session.json (\"sheet\")."},
    "xlsx.no_rows": {
        "en": "{file}: sheet '{sheet}' has no data rows; export the recording again.",
        "es": "{file}: la hoja '{sheet}' no tiene filas de datos; exporte de nuevo la grabación.",
        "pt": "{file}: a folha de cálculo '{sheet}' não tem linhas de dados; exporte a gravação de novo."},
    "xlsx.not_layout": {
        "en": "{file}: sheet '{sheet}' is not in the thesis layout: {problem}; fix row 1 or export the recording "
              "again.",
        "es": "{file}: la hoja '{sheet}' no tiene el formato de la tesis: {problem}; corrija la fila 1 o exporte "
              "de nuevo la grabación.",
        "pt": "{file}: a folha de cálculo '{sheet}' não tem o formato da tese: {problem}; corrija a linha 1 ou exporte a "
              "gravação de novo."},
    "xlsx.cell_not_number": {
        "en": "{file}: sheet '{sheet}', cell {cell} holds {value}, which is not a number; fix or delete that row.",
        "es": "{file}: hoja '{sheet}', la celda {cell} contiene {value}, que no es un número; corrija o borre esa "
              "fila.",
        "pt": "{file}: folha de cálculo '{sheet}', a célula {cell} contém {value}, que não é um número; corrija ou apague "
              "essa linha."},
    "xlsx.cell_infinite": {
        "en": "{file}: sheet '{sheet}', cell {cell} is infinite; fix or delete that row.",
        "es": "{file}: hoja '{sheet}', la celda {cell} es infinita; corrija o borre esa fila.",
        "pt": "{file}: folha de cálculo '{sheet}', a célula {cell} é infinita; corrija ou apague essa linha."},
    "xlsx.cell_huge": {
        "en": "{file}: sheet '{sheet}', cell {cell} holds {value}, beyond any time stamp or reading; fix or delete "
              "that row.",
        "es": "{file}: hoja '{sheet}', la celda {cell} contiene {value}, más que cualquier marca de tiempo o "
              "lectura; corrija o borre esa fila.",
        "pt": "{file}: folha de cálculo '{sheet}', a célula {cell} contém {value}, além de qualquer marca de tempo ou "
              "leitura; corrija ou apague essa linha."},
    "xlsx.unit_unknown": {
        "en": "{file}: unit ({unit}) in row 1 is not one ChakaMo knows for this column (acc g/mg/m/s², gyro "
              "deg/s/rad/s, mag T/mT/µT, time s/ms); correct row 1.",
        "es": "{file}: la unidad ({unit}) de la fila 1 no es una que ChakaMo conozca para esta columna (acc "
              "g/mg/m/s², giro deg/s/rad/s, mag T/mT/µT, tiempo s/ms); corrija la fila 1.",
        "pt": "{file}: a unidade ({unit}) da linha 1 não é uma que o ChakaMo conheça para esta coluna (acc "
              "g/mg/m/s², giro deg/s/rad/s, mag T/mT/µT, tempo s/ms); corrija a linha 1."},
    "xlsx.stream_empty": {
        "en": "{file}: sheet '{sheet}' has no {stream} data; export the recording again.",
        "es": "{file}: la hoja '{sheet}' no tiene datos de {stream}; exporte de nuevo la grabación.",
        "pt": "{file}: a folha de cálculo '{sheet}' não tem dados de {stream}; exporte a gravação de novo."},
    # -------------------------------------------------------------------------------------------- units
    "unit.unknown_for_stream": {
        "en": "{file}: unit ({unit}) is not one ChakaMo knows for the {stream} stream; expected {expected}; "
              "correct the unit in the column header.",
        "es": "{file}: la unidad ({unit}) no es una que ChakaMo conozca para el flujo {stream}; se esperaba "
              "{expected}; corrija la unidad en el encabezado de la columna.",
        "pt": "{file}: a unidade ({unit}) não é uma que o ChakaMo conheça para o fluxo {stream}; esperava-se "
              "{expected}; corrija a unidade no cabeçalho da coluna."},
    "unit.implausible_acc": {
        "en": "{file}: the accelerometer's typical magnitude is {value} m/s² when read as ({declared}); gravity is "
              "9.81 m/s². {hint} Correct the unit in the column header (or re-export the file in {declared}).",
        "es": "{file}: la magnitud típica del acelerómetro es {value} m/s² leída como ({declared}); la gravedad "
              "es 9,81 m/s². {hint} Corrija la unidad en el encabezado de la columna (o exporte de nuevo el "
              "archivo en {declared}).",
        "pt": "{file}: a magnitude típica do acelerómetro é {value} m/s² lida como ({declared}); a gravidade é "
              "9,81 m/s². {hint} Corrija a unidade no cabeçalho da coluna (ou exporte o ficheiro de novo em "
              "{declared})."},
    "unit.implausible_mag": {
        "en": "{file}: the magnetometer's typical field is {value} µT when read as ({declared}); the earth's "
              "field is 25–65 µT. {hint} Correct the unit in the column header (or re-export the file in "
              "{declared}).",
        "es": "{file}: el campo típico del magnetómetro es {value} µT leído como ({declared}); el campo "
              "terrestre es de 25–65 µT. {hint} Corrija la unidad en el encabezado de la columna (o exporte de "
              "nuevo el archivo en {declared}).",
        "pt": "{file}: o campo típico do magnetómetro é {value} µT lido como ({declared}); o campo da Terra é "
              "de 25–65 µT. {hint} Corrija a unidade no cabeçalho da coluna (ou exporte o ficheiro de novo em "
              "{declared})."},
    "unit.implausible_normalised": {
        "en": "{file}: the normalised magnetometer's typical norm is {value}, not about 1; check that the "
              "magnetometer columns are the normalised ones, or correct their unit in the header.",
        "es": "{file}: la norma típica del magnetómetro normalizado es {value}, no cerca de 1; compruebe que las "
              "columnas del magnetómetro son las normalizadas, o corrija su unidad en el encabezado.",
        "pt": "{file}: a norma típica do magnetómetro normalizado é {value}, não perto de 1; verifique se as "
              "colunas do magnetómetro são as normalizadas, ou corrija a sua unidade no cabeçalho."},
    "unit.gyr_beyond_range": {
        "en": "{file}: the gyroscope reaches {value} rad/s when read as ({declared}), beyond any IMU's range "
              "(35 rad/s = 2000 deg/s). {hint} Check the unit in the column header.",
        "es": "{file}: el giroscopio llega a {value} rad/s leído como ({declared}), más que el rango de cualquier "
              "IMU (35 rad/s = 2000 deg/s). {hint} Compruebe la unidad en el encabezado de la columna.",
        "pt": "{file}: o giroscópio chega a {value} rad/s lido como ({declared}), além do alcance de qualquer "
              "IMU (35 rad/s = 2000 deg/s). {hint} Verifique a unidade no cabeçalho da coluna."},
    "unit.gyr_looks_rad": {
        "en": "{file}: the gyroscope turns about {ratio}× less than the accelerometer shows the sensor turning; "
              "the numbers look like rad/s although the header declares ({declared}). Correct the unit in the "
              "column header to rad/s.",
        "es": "{file}: el giroscopio gira unas {ratio} veces menos de lo que el acelerómetro muestra que gira el "
              "sensor; los números parecen rad/s aunque el encabezado declara ({declared}). Corrija la unidad "
              "del encabezado a rad/s.",
        "pt": "{file}: o giroscópio gira cerca de {ratio} vezes menos do que o acelerómetro mostra o sensor "
              "girar; os números parecem rad/s embora o cabeçalho declare ({declared}). Corrija a unidade do "
              "cabeçalho para rad/s."},
    "unit.gyr_looks_deg": {
        "en": "{file}: the gyroscope turns about {ratio}× more than the accelerometer shows the sensor turning; "
              "the numbers look like deg/s although the header declares ({declared}). Correct the unit in the "
              "column header to deg/s.",
        "es": "{file}: el giroscopio gira unas {ratio} veces más de lo que el acelerómetro muestra que gira el "
              "sensor; los números parecen deg/s aunque el encabezado declara ({declared}). Corrija la unidad "
              "del encabezado a deg/s.",
        "pt": "{file}: o giroscópio gira cerca de {ratio} vezes mais do que o acelerómetro mostra o sensor "
              "girar; os números parecem deg/s embora o cabeçalho declare ({declared}). Corrija a unidade do "
              "cabeçalho para deg/s."},
    # -------------------------------------------------------------------------------------------- rates
    "rate.unexpected": {
        "en": "{file}: the {stream} stream runs at {fs_hz:.1f} Hz, expected {expected_hz:g} Hz (the protocol "
              "records accelerometer and gyroscope at 100 Hz, seed 004 §8.4). Record again at {expected_hz:g} Hz.",
        "es": "{file}: el flujo {stream} va a {fs_hz:.1f} Hz, se esperaban {expected_hz:g} Hz (el protocolo "
              "graba acelerómetro y giroscopio a 100 Hz). Grabe de nuevo a {expected_hz:g} Hz.",
        "pt": "{file}: o fluxo {stream} está a {fs_hz:.1f} Hz, esperavam-se {expected_hz:g} Hz (o protocolo "
              "grava acelerómetro e giroscópio a 100 Hz). Grave de novo a {expected_hz:g} Hz."},
    "rate.unexpected_any_rate": {
        "en": "{file}: the {stream} stream runs at {fs_hz:.1f} Hz, expected {expected_hz:g} Hz (the protocol "
              "records accelerometer and gyroscope at 100 Hz, seed 004 §8.4). Record again at {expected_hz:g} Hz, "
              "or process it at the file's own rate (on the command line: `chakamo process --any-rate`).",
        "es": "{file}: el flujo {stream} va a {fs_hz:.1f} Hz, se esperaban {expected_hz:g} Hz (el protocolo "
              "graba acelerómetro y giroscopio a 100 Hz). Grabe de nuevo a {expected_hz:g} Hz, o procéselo a la "
              "frecuencia del archivo (en la línea de órdenes: `chakamo process --any-rate`).",
        "pt": "{file}: o fluxo {stream} está a {fs_hz:.1f} Hz, esperavam-se {expected_hz:g} Hz (o protocolo "
              "grava acelerómetro e giroscópio a 100 Hz). Grave de novo a {expected_hz:g} Hz, ou processe-o na "
              "frequência do ficheiro (na linha de comando: `chakamo process --any-rate`)."},
    "rate.acc_gyr_differ": {
        "en": "{file}: the gyroscope runs at {gyr_hz:.1f} Hz but the accelerometer of recording '{label}' at "
              "{acc_hz:.1f} Hz; record both at the same rate.",
        "es": "{file}: el giroscopio va a {gyr_hz:.1f} Hz pero el acelerómetro de la grabación '{label}' a "
              "{acc_hz:.1f} Hz; grabe ambos a la misma frecuencia.",
        "pt": "{file}: o giroscópio está a {gyr_hz:.1f} Hz mas o acelerómetro da gravação '{label}' a "
              "{acc_hz:.1f} Hz; grave ambos na mesma frequência."},
    "rate.mag": {
        "en": "{file}: the magnetometer runs at {fs_hz:.1f} Hz; expected between {min_hz:g} and {max_hz:g} Hz (the "
              "protocol uses 20 Hz). Record again.",
        "es": "{file}: el magnetómetro va a {fs_hz:.1f} Hz; se esperaba entre {min_hz:g} y {max_hz:g} Hz (el "
              "protocolo usa 20 Hz). Grabe de nuevo.",
        "pt": "{file}: o magnetómetro está a {fs_hz:.1f} Hz; esperava-se entre {min_hz:g} e {max_hz:g} Hz (o "
              "protocolo usa 20 Hz). Grave de novo."},
    # ---------------------------------------------------------------------------------------- alignment
    "align.no_overlap": {
        "en": "{file}: the streams of this recording overlap for {seconds:.2f} s only (they must share at least "
              "1 s of time stamps); were they recorded together? Record again.",
        "es": "{file}: los flujos de esta grabación se solapan solo {seconds:.2f} s (deben compartir al menos "
              "1 s de marcas de tiempo); ¿se grabaron juntos? Grabe de nuevo.",
        "pt": "{file}: os fluxos desta gravação se sobrepõem só {seconds:.2f} s (devem partilhar pelo menos 1 s "
              "de marcas de tempo); foram gravados juntos? Grave de novo."},
    "align.no_overlap_pair": {
        "en": "{file}: the two sensors' task recordings overlap for {seconds:.2f} s only (they must share at least "
              "1 s of time stamps); were they recorded together? Record again.",
        "es": "{file}: las grabaciones de la tarea de los dos sensores se solapan solo {seconds:.2f} s (deben "
              "compartir al menos 1 s de marcas de tiempo); ¿se grabaron juntas? Grabe de nuevo.",
        "pt": "{file}: as gravações da tarefa dos dois sensores se sobrepõem só {seconds:.2f} s (devem partilhar "
              "pelo menos 1 s de marcas de tempo); foram gravadas juntas? Grave de novo."},
    "align.time_base_mixed": {
        "en": "{file}: has no epoch time stamps while the other streams of recording '{label}' have them, so they "
              "cannot be put on one time line; export it again with its 'epoch (ms)' column.",
        "es": "{file}: no tiene marcas de tiempo epoch mientras que los demás flujos de la grabación '{label}' sí, "
              "así que no se pueden poner en una línea de tiempo; expórtelo de nuevo con su columna 'epoch (ms)'.",
        "pt": "{file}: não tem marcas de tempo epoch enquanto os outros fluxos da gravação '{label}' têm, então "
              "não podem ser postos numa linha do tempo; exporte-o de novo com a sua coluna 'epoch (ms)'."},
    "align.pair_time_base": {
        "en": "{file} and {other}: one has epoch time stamps and the other not, so they cannot be put on one time "
              "line; export both the same way.",
        "es": "{file} y {other}: uno tiene marcas de tiempo epoch y el otro no, así que no se pueden poner en una "
              "línea de tiempo; exporte ambos de la misma manera.",
        "pt": "{file} e {other}: um tem marcas de tempo epoch e o outro não, então não podem ser postos numa "
              "linha do tempo; exporte ambos da mesma maneira."},
    # ------------------------------------------------------------------------------ recordings, session
    "recording.no_files": {
        "en": "a recording needs its files (none given); list them.",
        "es": "una grabación necesita sus archivos (no se dio ninguno); lístelos.",
        "pt": "uma gravação precisa dos seus ficheiros (nenhum foi dado); liste-os."},
    "recording.bad_file_set": {
        "en": "{file}: a recording is three MetaBase stream files, one .xlsx (thesis layout), one .h5 (APDM) or "
              "one .csv/.txt of a supported format; got {files}: list each recording's own files.",
        "es": "{file}: una grabación son tres archivos de flujo de MetaBase, un .xlsx (formato de la tesis), un "
              ".h5 (APDM) o un .csv/.txt de un formato admitido; se recibió {files}: liste los archivos propios de "
              "cada grabación.",
        "pt": "{file}: uma gravação são três ficheiros de fluxo do MetaBase, um .xlsx (formato da tese), um .h5 "
              "(APDM) ou um .csv/.txt de um formato suportado; recebeu-se {files}: liste os ficheiros próprios de "
              "cada gravação."},
    "session.no_folder": {
        "en": "{file}: no such session folder; check the path.",
        "es": "{file}: no existe esa carpeta de sesión; compruebe la ruta.",
        "pt": "{file}: essa pasta de sessão não existe; verifique o caminho."},
    "session.no_recordings": {
        "en": "{file}: no recordings found; the folder holds {count} file(s): {found}. ChakaMo reads MetaBase "
              "exports, thesis .xlsx, generic CSV, Xsens, APDM .h5, Shimmer, Sensor Logger (.zip) and phyphox files: "
              "check the folder, or export the recordings again. {hint}",
        "es": "{file}: no se encontró ninguna grabación; la carpeta tiene {count} archivo(s): {found}. ChakaMo lee "
              "exportaciones de MetaBase, .xlsx de la tesis, CSV genérico, Xsens, APDM .h5, Shimmer, Sensor Logger "
              "(.zip) y phyphox: compruebe la carpeta, o exporte de nuevo las grabaciones. {hint}",
        "pt": "{file}: nenhuma gravação encontrada; a pasta tem {count} ficheiro(s): {found}. O ChakaMo lê "
              "exportações do MetaBase, .xlsx da tese, CSV genérico, Xsens, APDM .h5, Shimmer, Sensor Logger "
              "(.zip) e phyphox: verifique a pasta, ou exporte as gravações de novo. {hint}"},
    "split.no_posture": {
        "en": "{file}: this continuous recording of the whole protocol has no {posture} posture held still for 5 s "
              "or more (still postures found, duration @ start (angle from the sensor's +y): {found}); record the protocol again holding standing and supine "
              "still for 30 s each, or export its parts as separate recordings.",
        "es": "{file}: esta grabación continua de todo el protocolo no tiene una postura {posture} mantenida "
              "quieta 5 s o más (posturas quietas encontradas, duración @ inicio (ángulo con el +y del sensor): {found}); grabe de nuevo el protocolo manteniendo "
              "quietas las posturas de pie y supina 30 s cada una, o exporte sus partes como grabaciones separadas.",
        "pt": "{file}: esta gravação contínua de todo o protocolo não tem uma postura {posture} mantida parada "
              "5 s ou mais (posturas paradas encontradas, duração @ início (ângulo com o +y do sensor): {found}); grave de novo o protocolo mantendo paradas as "
              "posturas em pé e dorsal 30 s cada, ou exporte as suas partes como gravações separadas."},
    "word.recording_group": {  # a fragment of app.pipeline.service_messages "session.recognised"
        "en": "{label} ({n} {format} files)",
        "es": "{label} ({n} archivos {format})",
        "pt": "{label} ({n} ficheiros {format})"},
    "session.recording_twice": {
        "en": "{file} and {other} are both the {role} recording of the {segment}; keep one (or list the one to use "
              "in session.json).",
        "es": "{file} y {other} son ambos la grabación {role} del {segment}; conserve una (o liste en "
              "session.json la que se debe usar).",
        "pt": "{file} e {other} são ambos a gravação {role} da {segment}; mantenha uma (ou liste no session.json "
              "a que deve ser usada)."},
    "session.one_sensor": {
        "en": "{file}: only the {segment} sensor found; a session needs both the thigh and the shank sensor (knee "
              "angles compare the two). {hint}",
        "es": "{file}: solo se encontró el sensor del {segment}; una sesión necesita el sensor del muslo y el de "
              "la pierna (los ángulos de rodilla comparan ambos). {hint}",
        "pt": "{file}: só foi encontrado o sensor da {segment}; uma sessão precisa do sensor da coxa e do da "
              "perna (os ângulos do joelho comparam os dois). {hint}"},
    "session.two_knees": {
        "en": "{file}: the recordings are of both knees (four sensors); process the folder as a two-knee session "
              "(chakamo process, or the web application's processing).",
        "es": "{file}: las grabaciones son de ambas rodillas (cuatro sensores); procese la carpeta como sesión de "
              "dos rodillas (chakamo process, o el procesamiento de la aplicación web).",
        "pt": "{file}: as gravações são dos dois joelhos (quatro sensores); processe a pasta como sessão de dois "
              "joelhos (chakamo process, ou o processamento da aplicação web)."},
    "session.side_unknown": {
        "en": "{file}: the session has recordings of both knees, but {files} does not say which side it is; add "
              "right or left to its name, or \"side\" to its entry in session.json.",
        "es": "{file}: la sesión tiene grabaciones de ambas rodillas, pero {files} no dice de qué lado es; añada "
              "derecha o izquierda a su nombre, o \"side\" a su entrada en session.json.",
        "pt": "{file}: a sessão tem gravações dos dois joelhos, mas {files} não diz de que lado é; acrescente "
              "direita ou esquerda ao nome, ou \"side\" à sua entrada no session.json."},
    "manifest.paired_not_found": {
        "en": "{file}: paired_session = '{value}' is not a session folder; give the path of the other knee's "
              "folder, relative to this one (e.g. ../left-knee).",
        "es": "{file}: paired_session = '{value}' no es una carpeta de sesión; dé la ruta de la carpeta de la otra "
              "rodilla, relativa a esta (p. ej. ../rodilla-izquierda).",
        "pt": "{file}: paired_session = '{value}' não é uma pasta de sessão; dê o caminho da pasta do outro "
              "joelho, relativo a esta (p. ex. ../joelho-esquerdo)."},
    "manifest.paired_same_side": {
        "en": "{file}: this session's side is {side} and the paired session {other}'s is {other_side}; a pair "
              "needs one right and one left knee, each named (\"side\" in each session.json).",
        "es": "{file}: el lado de esta sesión es {side} y el de la sesión emparejada {other} es {other_side}; un "
              "par necesita una rodilla derecha y una izquierda, cada una nombrada (\"side\" en cada session.json).",
        "pt": "{file}: o lado desta sessão é {side} e o da sessão pareada {other} é {other_side}; um par precisa "
              "de um joelho direito e um esquerdo, cada um nomeado (\"side\" em cada session.json)."},
    "session.no_sensor": {
        "en": "{file}: no sensor found; a session needs both the thigh and the shank sensor (knee angles compare "
              "the two). {hint}",
        "es": "{file}: no se encontró ningún sensor; una sesión necesita el sensor del muslo y el de la pierna "
              "(los ángulos de rodilla comparan ambos). {hint}",
        "pt": "{file}: nenhum sensor encontrado; uma sessão precisa do sensor da coxa e do da perna (os ângulos "
              "do joelho comparam os dois). {hint}"},
    "session.missing_recordings": {
        "en": "{file}: missing recording(s): {missing}. {hint}",
        "es": "{file}: falta(n) grabación(es): {missing}. {hint}",
        "pt": "{file}: falta(m) gravação(ões): {missing}. {hint}"},
    # ------------------------------------------------------------------------------------ session.json
    "manifest.not_utf8": {
        "en": "{file}: not UTF-8 text; save it again as UTF-8 (or remove the file).",
        "es": "{file}: no es texto UTF-8; guárdelo de nuevo como UTF-8 (o elimine el archivo).",
        "pt": "{file}: não é texto UTF-8; guarde-o de novo como UTF-8 (ou remova o ficheiro)."},
    "manifest.invalid_json": {
        "en": "{file}: not valid JSON (line {line}, column {col}: {reason}); fix it or remove the file.",
        "es": "{file}: no es JSON válido (línea {line}, columna {col}: {reason}); corríjalo o elimine el archivo.",
        "pt": "{file}: não é JSON válido (linha {line}, coluna {col}: {reason}); corrija-o ou remova o ficheiro."},
    "manifest.not_object": {
        "en": "{file}: must be a JSON object with keys {keys}; fix it or remove the file.",
        "es": "{file}: debe ser un objeto JSON con las claves {keys}; corríjalo o elimine el archivo.",
        "pt": "{file}: deve ser um objeto JSON com as chaves {keys}; corrija-o ou remova o ficheiro."},
    "manifest.unknown_keys": {
        "en": "{file}: unknown keys {unknown}; use only {keys} (remove or rename the others).",
        "es": "{file}: claves desconocidas {unknown}; use solo {keys} (elimine o renombre las demás).",
        "pt": "{file}: chaves desconhecidas {unknown}; use só {keys} (remova ou renomeie as outras)."},
    "manifest.wrong_type": {
        "en": "{file}: {key} = {value} must be {expected}; correct it.",
        "es": "{file}: {key} = {value} debe ser {expected}; corríjalo.",
        "pt": "{file}: {key} = {value} deve ser {expected}; corrija-o."},
    "manifest.sensor_segment_type": {
        "en": "{file}: sensors['{mac}'] = {value}; give the segment as a string (\"thigh\" or \"shank\").",
        "es": "{file}: sensors['{mac}'] = {value}; dé el segmento como texto (\"thigh\" o \"shank\").",
        "pt": "{file}: sensors['{mac}'] = {value}; dê o segmento como texto (\"thigh\" ou \"shank\")."},
    "manifest.recordings_empty": {
        "en": "{file}: 'recordings' lists no recording; list the session's files, or remove the key to let "
              "ChakaMo find them.",
        "es": "{file}: 'recordings' no lista ninguna grabación; liste los archivos de la sesión, o elimine la "
              "clave para que ChakaMo los encuentre.",
        "pt": "{file}: 'recordings' não lista nenhuma gravação; liste os ficheiros da sessão, ou remova a chave "
              "para o ChakaMo encontrá-los."},
    "manifest.bad_entry": {
        "en": "{file}: recordings[{index}] must be an object with 'files' (a non-empty list of names) and optional "
              "'segment', 'role', 'sheet' (strings); correct it.",
        "es": "{file}: recordings[{index}] debe ser un objeto con 'files' (una lista no vacía de nombres) y "
              "opcionalmente 'segment', 'role', 'sheet' (textos); corríjalo.",
        "pt": "{file}: recordings[{index}] deve ser um objeto com 'files' (uma lista não vazia de nomes) e "
              "opcionalmente 'segment', 'role', 'sheet' (textos); corrija-o."},
    "manifest.file_outside": {
        "en": "{file}: recordings[{index}] lists {name}, which is not a file inside the session folder; list the "
              "recordings by their names in this folder.",
        "es": "{file}: recordings[{index}] lista {name}, que no es un archivo dentro de la carpeta de la sesión; "
              "liste las grabaciones por sus nombres en esta carpeta.",
        "pt": "{file}: recordings[{index}] lista {name}, que não é um ficheiro dentro da pasta da sessão; liste as "
              "gravações pelos seus nomes nesta pasta."},
    # a session.json stored by the web (app.store.workspace): fixed by deleting that recording and uploading anew
    "manifest.stored_not_json": {
        "en": "{file}: not valid UTF-8 JSON; fix it or delete that recording.",
        "es": "{file}: no es JSON UTF-8 válido; corríjalo o borre esa grabación.",
        "pt": "{file}: não é JSON UTF-8 válido; corrija-o ou apague essa gravação."},
    "manifest.stored_not_object": {
        "en": "{file}: must be a JSON object ({{\"side\": ..., \"recordings\": [...]}}), not {kind}; fix it or delete "
              "that recording.",
        "es": "{file}: debe ser un objeto JSON ({{\"side\": ..., \"recordings\": [...]}}), no {kind}; corríjalo o "
              "borre esa grabación.",
        "pt": "{file}: deve ser um objeto JSON ({{\"side\": ..., \"recordings\": [...]}}), não {kind}; corrija-o ou "
              "apague essa gravação."},
    "manifest.stored_recordings_not_list": {
        "en": "{file}: \"recordings\" must be a list of {{\"files\": [...], \"segment\": ..., \"role\": ...}} "
              "entries; fix it or delete that recording.",
        "es": "{file}: \"recordings\" debe ser una lista de entradas {{\"files\": [...], \"segment\": ..., "
              "\"role\": ...}}; corríjalo o borre esa grabación.",
        "pt": "{file}: \"recordings\" deve ser uma lista de entradas {{\"files\": [...], \"segment\": ..., "
              "\"role\": ...}}; corrija-o ou apague essa gravação."},
    "manifest.not_uploaded": {  # the web: a stored session.json naming a file the session does not hold
        "en": "{file}: the recording file {name} is not one of this session's uploaded files; list only the "
              "uploaded files' names, or delete that recording.",
        "es": "{file}: el archivo de grabación {name} no es uno de los archivos subidos a esta sesión; liste solo "
              "los nombres de los archivos subidos, o borre esa grabación.",
        "pt": "{file}: o ficheiro de gravação {name} não é um dos ficheiros enviados a esta sessão; liste só os "
              "nomes dos ficheiros enviados, ou apague essa gravação."},
    "manifest.file_twice": {
        "en": "{file}: '{name}' is listed twice (recordings[{first}] and recordings[{second}]); list each file "
              "once.",
        "es": "{file}: '{name}' aparece dos veces (recordings[{first}] y recordings[{second}]); liste cada "
              "archivo una vez.",
        "pt": "{file}: '{name}' aparece duas vezes (recordings[{first}] e recordings[{second}]); liste cada "
              "ficheiro uma vez."},
    "manifest.unknown_segment": {
        "en": "{file}: {where} = '{value}' is not a segment ChakaMo knows; use one of {allowed}.",
        "es": "{file}: {where} = '{value}' no es un segmento que ChakaMo conozca; use uno de {allowed}.",
        "pt": "{file}: {where} = '{value}' não é um segmento que o ChakaMo conheça; use um de {allowed}."},
    "manifest.unknown_role": {
        "en": "{file}: {where} = '{value}' is not a role ChakaMo knows; use one of {allowed}.",
        "es": "{file}: {where} = '{value}' no es un papel que ChakaMo conozca; use uno de {allowed}.",
        "pt": "{file}: {where} = '{value}' não é um papel que o ChakaMo conheça; use um de {allowed}."},
    "manifest.bad_side": {
        "en": "{file}: side = '{value}'; use 'right' or 'left'.",
        "es": "{file}: side = '{value}'; use 'right' o 'left'.",
        "pt": "{file}: side = '{value}'; use 'right' ou 'left'."},
    "manifest.bad_step_height": {
        "en": "{file}: step_height_m = {value}; give the step height in metres, e.g. 0.17.",
        "es": "{file}: step_height_m = {value}; dé la altura del escalón en metros, p. ej. 0.17.",
        "pt": "{file}: step_height_m = {value}; dê a altura do degrau em metros, p. ex. 0.17."},
    "manifest.bad_field": {
        "en": "{file}: mag_field_ut = {value}; give the local magnetic field strength in µT (25–65), e.g. 48.5.",
        "es": "{file}: mag_field_ut = {value}; dé la intensidad del campo magnético local en µT (25–65), p. ej. 48.5.",
        "pt": "{file}: mag_field_ut = {value}; dê a intensidade do campo magnético local em µT (25–65), p. ex. 48.5."},
    "manifest.bad_split": {
        "en": "{file}: split of the {segment} = {value}; give each cut as \"role\": [start_s, end_s] (seconds from the "
              "recording's start, start before end) with roles among {roles}, as results.json session.split shows.",
        "es": "{file}: split del {segment} = {value}; dé cada corte como \"papel\": [inicio_s, fin_s] (segundos desde "
              "el inicio de la grabación, inicio antes que fin) con papeles entre {roles}, como los muestra "
              "session.split de results.json.",
        "pt": "{file}: split da {segment} = {value}; dê cada corte como \"papel\": [início_s, fim_s] (segundos desde o "
              "início da gravação, início antes do fim) com papéis entre {roles}, como os mostra session.split do "
              "results.json."},
    # ------------------------------------------------------------------- size caps (issue 16, findings 4, 5)
    "xlsx.too_big": {
        "en": "{file}: its part {member} would take {size_mb} MB once unpacked, more than the {limit_mb} MB a "
              "recording's workbook may take; check that it is a recording of this session, or save it as CSV.",
        "es": "{file}: su parte {member} ocuparía {size_mb} MB al descomprimirse, más de los {limit_mb} MB que "
              "puede ocupar el libro de una grabación; compruebe que es una grabación de esta sesión, o guárdelo "
              "como CSV.",
        "pt": "{file}: a sua parte {member} ocuparia {size_mb} MB ao ser descompactada, mais que os {limit_mb} MB "
              "que o livro de uma gravação pode ocupar; verifique se é uma gravação desta sessão, ou "
              "guarde-o como CSV."},
    "zip.too_big": {
        "en": "{file}: its file {member} would take {size_mb} MB once unpacked, more than the {limit_mb} MB a "
              "recording's export may take; check that it is the export of a recording of this session, or export "
              "it again.",
        "es": "{file}: su archivo {member} ocuparía {size_mb} MB al descomprimirse, más de los {limit_mb} MB que "
              "puede ocupar la exportación de una grabación; compruebe que es la exportación de una grabación de "
              "esta sesión, o expórtela de nuevo.",
        "pt": "{file}: o seu ficheiro {member} ocuparia {size_mb} MB ao ser descompactado, mais que os {limit_mb} MB "
              "que a exportação de uma gravação pode ocupar; verifique se é a exportação de uma gravação desta "
              "sessão, ou exporte-a de novo."},
    "zip.too_many_members": {
        "en": "{file}: the zip holds {count} files (at most {limit}); export the recording again from the app.",
        "es": "{file}: el zip contiene {count} archivos (como mucho {limit}); exporte de nuevo la grabación desde "
              "la aplicación.",
        "pt": "{file}: o zip contém {count} ficheiros (no máximo {limit}); exporte a gravação de novo a partir do "
              "aplicação."},
    "xlsx.too_many_parts": {
        "en": "{file}: the workbook holds {count} parts (at most {limit}); save it again from Excel as .xlsx.",
        "es": "{file}: el libro contiene {count} partes (como mucho {limit}); guárdelo de nuevo desde Excel "
              "como .xlsx.",
        "pt": "{file}: o livro contém {count} partes (no máximo {limit}); guarde-o de novo no Excel "
              "como .xlsx."},
    "xlsx.too_many_rows": {
        "en": "{file}: sheet '{sheet}' has more than {limit} rows (more than {minutes} minutes at 100 Hz); "
              "split the recording into shorter ones, or export it as CSV.",
        "es": "{file}: la hoja '{sheet}' tiene más de {limit} filas (más de {minutes} minutos a 100 Hz); divida "
              "la grabación en otras más cortas, o expórtela como CSV.",
        "pt": "{file}: a folha de cálculo '{sheet}' tem mais de {limit} linhas (mais de {minutes} minutos a 100 Hz); "
              "divida a gravação em outras mais curtas, ou exporte-a como CSV."},
    "xlsx.too_many_cells": {
        "en": "{file}: sheet '{sheet}' holds {cells} cells (at most {limit}); delete what lies outside the "
              "columns A–M of the thesis layout, or export the recording again.",
        "es": "{file}: la hoja '{sheet}' contiene {cells} celdas (como mucho {limit}); borre lo que está fuera "
              "de las columnas A–M del formato de la tesis, o exporte de nuevo la grabación.",
        "pt": "{file}: a folha de cálculo '{sheet}' contém {cells} células (no máximo {limit}); apague o que está fora "
              "das colunas A–M do formato da tese, ou exporte a gravação de novo."},
    "xlsx.too_many_strings": {
        "en": "{file}: its shared texts ({member}) hold {count} entries, more than the {limit} its sheets' cells "
              "could show; save the workbook again from Excel as .xlsx, or export the recording as CSV.",
        "es": "{file}: sus textos compartidos ({member}) contienen {count} entradas, más de las {limit} que "
              "pueden mostrar las celdas de sus hojas; guarde de nuevo el libro desde Excel como .xlsx, o exporte "
              "la grabación como CSV.",
        "pt": "{file}: os seus textos partilhados ({member}) contêm {count} entradas, mais que as {limit} que as "
              "células das suas folhas de cálculo podem mostrar; guarde o livro de novo no Excel como "
              ".xlsx, ou exporte a gravação como CSV."},
    "manifest.too_large": {
        "en": "{file}: {size_kb} kB, more than the {limit_kb} kB a session.json may take; keep only the keys "
              "it documents.",
        "es": "{file}: {size_kb} kB, más de los {limit_kb} kB que puede ocupar un session.json; deje solo las "
              "claves que documenta.",
        "pt": "{file}: {size_kb} kB, mais que os {limit_kb} kB que um session.json pode ocupar; deixe só as "
              "chaves que ele documenta."},
    "manifest.too_deep": {
        "en": "{file}: nested more than {limit} levels deep; a session.json needs 4 (the object → recordings → "
              "an entry → files); fix it or remove the file.",
        "es": "{file}: anidado a más de {limit} niveles; un session.json necesita 4 (el objeto → recordings → "
              "una entrada → files); corríjalo o elimine el archivo.",
        "pt": "{file}: aninhado a mais de {limit} níveis; um session.json precisa de 4 (o objeto → recordings → "
              "uma entrada → files); corrija-o ou remova o ficheiro."},
    # ------------------------------------------------------------------------------- provenance checks
    "check.side_mismatch": {
        "en": "{file}: the recording says the {found} leg ({method}) but the patient's knee is the {patient_side}; "
              "adduction and rotation would flip sign. Check the patient's side or the files; the clinician may "
              "override this.",
        "es": "{file}: la grabación dice pierna {found} ({method}) pero la rodilla del paciente es la "
              "{patient_side}; la aducción y la rotación cambiarían de signo. Compruebe el lado del paciente o los "
              "archivos; el clínico puede forzarlo.",
        "pt": "{file}: a gravação diz perna {found} ({method}) mas o joelho do paciente é o {patient_side}; a "
              "adução e a rotação mudariam de sinal. Verifique o lado do paciente ou os ficheiros; o clínico pode "
              "forçá-lo."},
    "check.date_far": {
        "en": "{file}: recorded on {date}, {days} days from the session date {session_date}; check that it "
              "belongs to this session (or correct the session date).",
        "es": "{file}: grabado el {date}, a {days} días de la fecha de la sesión {session_date}; compruebe que "
              "pertenece a esta sesión (o corrija la fecha de la sesión).",
        "pt": "{file}: gravado em {date}, a {days} dias da data da sessão {session_date}; verifique se pertence "
              "a esta sessão (ou corrija a data da sessão)."},
    "check.dates_spread": {
        "en": "the recordings span {days} days ({first_file} on {first}, {last_file} on {last}); check that they "
              "all belong to one session.",
        "es": "las grabaciones abarcan {days} días ({first_file} el {first}, {last_file} el {last}); compruebe que "
              "todas pertenecen a una misma sesión.",
        "pt": "as gravações abrangem {days} dias ({first_file} em {first}, {last_file} em {last}); verifique se "
              "todas pertencem a uma mesma sessão."},
    "check.patient_mismatch": {
        "en": "{file}: the patient id is {found} ({method}), not {patient_id}; check that the files are this "
              "patient's.",
        "es": "{file}: el identificador del paciente es {found} ({method}), no {patient_id}; compruebe que los "
              "archivos son de este paciente.",
        "pt": "{file}: o identificador do paciente é {found} ({method}), não {patient_id}; verifique se os "
              "ficheiros são deste paciente."},
    "check.sensor_both_segments": {
        "en": "sensor {sensor} recorded the thigh in {thigh_file} and the shank in {shank_file}; check that the "
              "sensors were not swapped between recordings (or correct the names / session.json).",
        "es": "el sensor {sensor} grabó el muslo en {thigh_file} y la pierna en {shank_file}; compruebe que los "
              "sensores no se intercambiaron entre grabaciones (o corrija los nombres / session.json).",
        "pt": "o sensor {sensor} gravou a coxa em {thigh_file} e a perna em {shank_file}; verifique se os "
              "sensores não foram trocados entre gravações (ou corrija os nomes / session.json)."},
    # ---------------------------------------------------------------------------------------- fragments
    "hint.ignored_csv": {
        "en": "Ignored {file} (not a file of a format ChakaMo reads).",
        "es": "Se ignoró {file} (no es un archivo de un formato que ChakaMo lea).",
        "pt": "Ignorado {file} (não é um ficheiro de um formato que o ChakaMo leia)."},
    "hint.unrecognised": {
        "en": "Files not recognised: {file} ({what} not recognised{why}).",
        "es": "Archivos no reconocidos: {file} ({what} no reconocido{why}).",
        "pt": "Ficheiros não reconhecidos: {file} ({what} não reconhecido{why})."},
    "hint.naming": {
        "en": "Name files like step-muslo-ML1-13032023-1.xlsx / standing-pierna-..., or list them in {manifest} "
              "with segment and role.",
        "es": "Nombre los archivos como step-muslo-ML1-13032023-1.xlsx / standing-pierna-..., o lístelos en "
              "{manifest} con segmento y papel.",
        "pt": "Nomeie os ficheiros como step-muslo-ML1-13032023-1.xlsx / standing-pierna-..., ou liste-os no "
              "{manifest} com segmento e papel."},
    "hint.looks_like": {
        "en": "The numbers look like {unit}, not {declared}.",
        "es": "Los números parecen {unit}, no {declared}.",
        "pt": "Os números parecem {unit}, não {declared}."},
    "word.role": {"en": "role", "es": "papel", "pt": "papel"},
    "word.segment": {"en": "segment", "es": "segmento", "pt": "segmento"},
    "word.role_segment": {"en": "role and segment", "es": "papel y segmento", "pt": "papel e segmento"},
    "word.side": {"en": "side", "es": "lado", "pt": "lado"},
    "word.ambiguity": {"en": ": {reasons}", "es": ": {reasons}", "pt": ": {reasons}"},   # hint.unrecognised's why
    "word.label_ambiguous": {  # a file name naming two roles or segments (labels.AmbiguousLabel)
        "en": "the label '{label}' names more than one {what}: {found}",
        "es": "la etiqueta '{label}' nombra más de un {what}: {found}",
        "pt": "o rótulo '{label}' nomeia mais de um {what}: {found}"},
    "word.role_of": {"en": "{role} of the {segment}", "es": "{role} ({segment})", "pt": "{role} ({segment})"},
    # -------------------------------------------------------------------------------------------- notes
    "note.csv_semicolon": {
        "en": "{file}: read with ';' between fields and ',' as the decimal point (a spreadsheet in Spanish or "
              "Portuguese saved it)",
        "es": "{file}: leído con ';' entre campos y ',' como separador decimal (lo guardó una hoja de cálculo en "
              "español o portugués)",
        "pt": "{file}: lido com ';' entre campos e ',' como separador decimal (guardado por uma folha de cálculo em "
              "espanhol ou português)"},
    "note.truncated_last_row": {
        "en": "{file}: the last row ({row}) was cut short (an interrupted copy or export) and was dropped",
        "es": "{file}: la última fila ({row}) estaba cortada (una copia o exportación interrumpida) y se descartó",
        "pt": "{file}: a última linha ({row}) estava cortada (uma cópia ou exportação interrompida) e foi "
              "descartada"},
    "note.duplicate_rows": {
        "en": "{file}: {rows} row(s) repeated exactly (first at row {first_row}) were dropped",
        "es": "{file}: se descartaron {rows} fila(s) repetida(s) exactamente (la primera en la fila {first_row})",
        "pt": "{file}: foram descartadas {rows} linha(s) repetida(s) exatamente (a primeira na linha {first_row})"},
    "note.excel_epoch_rebuilt": {
        "en": "{file}: '{column}' was rounded by a spreadsheet; time rebuilt from 'elapsed (s)' and the start "
              "time in the file name ({start}, phone's local time)",
        "es": "{file}: '{column}' fue redondeado por una hoja de cálculo; el tiempo se reconstruyó con "
              "'elapsed (s)' y la hora de inicio del nombre del archivo ({start}, hora local del teléfono)",
        "pt": "{file}: '{column}' foi arredondado por uma folha de cálculo; o tempo foi reconstruído com 'elapsed (s)' "
              "e a hora de início do nome do ficheiro ({start}, hora local do telefone)"},
    "note.excel_epoch_offset": {
        "en": "{file}: rebuilt time put on UTC with the phone's offset seen in the session's other files "
              "({offset_h:+.2f} h)",
        "es": "{file}: el tiempo reconstruido se pasó a UTC con el desfase del teléfono visto en los demás "
              "archivos de la sesión ({offset_h:+.2f} h)",
        "pt": "{file}: o tempo reconstruído foi passado a UTC com o desvio do telefone visto nos outros ficheiros "
              "da sessão ({offset_h:+.2f} h)"},
    "note.excel_epoch_local": {
        "en": "{file}: rebuilt time stays on the phone's local time (no file of the session kept its epoch); "
              "wall-clock times in messages are local",
        "es": "{file}: el tiempo reconstruido queda en la hora local del teléfono (ningún archivo de la sesión "
              "conservó su epoch); las horas de los mensajes son locales",
        "pt": "{file}: o tempo reconstruído fica na hora local do telefone (nenhum ficheiro da sessão manteve o "
              "seu epoch); as horas nas mensagens são locais"},
    "note.csv_ignored": {
        "en": "ignored {file} (not a file of a format ChakaMo reads)",
        "es": "se ignoró {file} (no es un archivo de un formato que ChakaMo lea)",
        "pt": "ignorado {file} (não é um ficheiro de um formato que o ChakaMo leia)"},
    "note.file_unrecognised": {
        "en": "ignored {file} ({what} not recognised{why})",
        "es": "se ignoró {file} ({what} no reconocido{why})",
        "pt": "ignorado {file} ({what} não reconhecido{why})"},
    "note.phone_ios_frames": {
        "en": "{file}: an iPhone recording: acceleration and gravity taken with Sensor Logger's default frames "
              "(\"Standardise Units & Frames\" off) and turned to specific force",
        "es": "{file}: grabación de iPhone: aceleración y gravedad tomadas con los ejes por defecto de Sensor "
              "Logger (\"Standardise Units & Frames\" desactivado) y pasadas a fuerza específica",
        "pt": "{file}: gravação de iPhone: aceleração e gravidade tomadas com os eixos padrão do Sensor Logger "
              "(\"Standardise Units & Frames\" desligado) e passadas a força específica"},
    "note.no_mag_calibration": {
        "en": "{file}: no figure-eight (magnetometer calibration) recording: the magnetometers' own factory "
              "calibration is used, without the ellipsoid fit",
        "es": "{file}: no hay grabación en ocho (calibración del magnetómetro): se usa la calibración de fábrica de "
              "los magnetómetros, sin el ajuste del elipsoide",
        "pt": "{file}: não há gravação em oito (calibração do magnetómetro): usa-se a calibração de fábrica dos "
              "magnetómetros, sem o ajuste do elipsoide"},
    "note.no_lying": {
        "en": "{file}: no supine recording: the segment axes come from standing and the knee's hinge axes on the task",
        "es": "{file}: no hay grabación en decúbito supino: los ejes de los segmentos se toman de la postura de pie y "
              "de los ejes de bisagra de la rodilla en la tarea",
        "pt": "{file}: não há gravação em decúbito dorsal: os eixos dos segmentos vêm da postura em pé e dos eixos de "
              "dobradiça do joelho na tarefa"},
    "note.sheet_chosen": {
        "en": "sheet {sheet!r}",
        "es": "hoja {sheet!r}",
        "pt": "folha {sheet!r}"},
    "note.sheet_chosen_of": {
        "en": "sheet {sheet!r} of {sheets}",
        "es": "hoja {sheet!r} de {sheets}",
        "pt": "folha {sheet!r} de {sheets}"},
    "note.file_sheet_chosen": {
        "en": "{file}: sheet {sheet!r}",
        "es": "{file}: hoja {sheet!r}",
        "pt": "{file}: folha {sheet!r}"},
    "note.file_sheet_chosen_of": {
        "en": "{file}: sheet {sheet!r} of {sheets}",
        "es": "{file}: hoja {sheet!r} de {sheets}",
        "pt": "{file}: folha {sheet!r} de {sheets}"},
    "note.names_disagree": {
        "en": "file names disagree on {key}: {values}; used {used}",
        "es": "los nombres de archivo no coinciden en {key}: {values}; se usó {used}",
        "pt": "os nomes de ficheiro não coincidem em {key}: {values}; foi usado {used}"},
    "note.csv_decimal_comma": {
        "en": "{file}: read with tabs between fields and ',' as the decimal point",
        "es": "{file}: leído con tabuladores entre campos y ',' como separador decimal",
        "pt": "{file}: lido com tabulações entre campos e ',' como separador decimal"},
    "note.recording_split": {
        "en": "{file}: one continuous recording, split into figure-eight "
              "{mag_calibration_from_s:.1f}–{mag_calibration_to_s:.1f} s, standing "
              "{standing_from_s:.1f}–{standing_to_s:.1f} s, supine {lying_from_s:.1f}–{lying_to_s:.1f} s and task "
              "from {task_from_s:.1f} s (seconds from its start); if a part is misplaced, set its cut in "
              "session.json \"split\" or export the parts as separate recordings",
        "es": "{file}: una grabación continua, dividida en ocho "
              "{mag_calibration_from_s:.1f}–{mag_calibration_to_s:.1f} s, de pie "
              "{standing_from_s:.1f}–{standing_to_s:.1f} s, supino {lying_from_s:.1f}–{lying_to_s:.1f} s y tarea "
              "desde {task_from_s:.1f} s (segundos desde su inicio); si una parte está mal situada, fije su corte "
              "en \"split\" de session.json o exporte las partes como grabaciones separadas",
        "pt": "{file}: uma gravação contínua, dividida em oito "
              "{mag_calibration_from_s:.1f}–{mag_calibration_to_s:.1f} s, em pé "
              "{standing_from_s:.1f}–{standing_to_s:.1f} s, decúbito dorsal {lying_from_s:.1f}–{lying_to_s:.1f} s e "
              "tarefa a partir de {task_from_s:.1f} s (segundos desde o início); se uma parte estiver mal situada, "
              "fixe o seu corte em \"split\" do session.json ou exporte as partes como gravações separadas"},
    "note.recording_split_no_fig8": {
        "en": "{file}: one continuous recording, split into standing {standing_from_s:.1f}–{standing_to_s:.1f} s, "
              "supine {lying_from_s:.1f}–{lying_to_s:.1f} s and task from {task_from_s:.1f} s (seconds from its "
              "start); no figure-eight found in it; if a part is misplaced, set its cut in session.json \"split\" or "
              "export the parts as separate recordings",
        "es": "{file}: una grabación continua, dividida en de pie {standing_from_s:.1f}–{standing_to_s:.1f} s, "
              "supino {lying_from_s:.1f}–{lying_to_s:.1f} s y tarea desde {task_from_s:.1f} s (segundos desde su "
              "inicio); no se encontró un ocho en ella; si una parte está mal situada, fije su corte en \"split\" de "
              "session.json o exporte las partes como grabaciones separadas",
        "pt": "{file}: uma gravação contínua, dividida em em pé {standing_from_s:.1f}–{standing_to_s:.1f} s, "
              "decúbito dorsal {lying_from_s:.1f}–{lying_to_s:.1f} s e tarefa a partir de {task_from_s:.1f} s "
              "(segundos desde o início); não foi encontrado um oito nela; se uma parte estiver mal situada, fixe o "
              "seu corte em \"split\" do session.json ou exporte as partes como gravações separadas"},
    "note.no_standing": {
        "en": "{file}: no standing recording: the segment axes come from the task alone, which must hold the knee "
              "straight and still for 2 s (standing before it starts)",
        "es": "{file}: no hay grabación de pie: los ejes de los segmentos se toman solo de la tarea, que debe mantener "
              "la rodilla extendida y quieta 2 s (de pie antes de empezar)",
        "pt": "{file}: não há gravação em pé: os eixos dos segmentos vêm só da tarefa, que deve manter o joelho "
              "estendido e parado 2 s (em pé antes de começar)"},
    "note.mag_normalised": {
        "en": "{file}: magnetometer in normalised units (no µT scale; declared field strength: {field}); the "
              "vendor calibrated it, so no figure-eight fit in µT applies",
        "es": "{file}: magnetómetro en unidades normalizadas (sin escala en µT; intensidad de campo declarada: "
              "{field}); lo calibró el fabricante, así que no se aplica un ajuste de ocho en µT",
        "pt": "{file}: magnetómetro em unidades normalizadas (sem escala em µT; intensidade de campo declarada: "
              "{field}); o fabricante calibrou-o, por isso não se aplica um ajuste em oito em µT"},
    # the store's refusal of an interpretation written by someone else meanwhile (app.store.interpretations):
    # here, the catalogue app.store.errors falls back to, until it moves beside the other store.interpretation_*
}

#: Segment and role words for the "<segment> <role>:" prefix of a session's notes.
WORDS = {
    "thigh": {"en": "thigh", "es": "muslo", "pt": "coxa"},
    "shank": {"en": "shank", "es": "pierna", "pt": "perna"},
    "mag_calibration": {"en": "mag_calibration", "es": "calibración magnética", "pt": "calibração magnética"},
    "standing": {"en": "standing", "es": "de pie", "pt": "em pé"},
    "lying": {"en": "lying", "es": "tumbado", "pt": "deitado"},
    "task": {"en": "task", "es": "tarea", "pt": "tarefa"},
    "continuous": {"en": "continuous", "es": "continua", "pt": "contínua"},
    "right": {"en": "right", "es": "derecha", "pt": "direita"},
    # how a segment or role was recognised (Recognition.method), for the session check's lines
    "how_file_name": {"en": "the file name", "es": "el nombre del archivo", "pt": "o nome do ficheiro"},
    "how_metabase_label": {"en": "the MetaBase label", "es": "la etiqueta de MetaBase", "pt": "o rótulo do MetaBase"},
    "how_session_json": {"en": "session.json", "es": "session.json", "pt": "session.json"},
    "how_split": {"en": "the split of the continuous recording", "es": "la división de la grabación continua",
                  "pt": "a divisão da gravação contínua"},
    "left": {"en": "left", "es": "izquierda", "pt": "esquerda"},
}


CATALOGUE.update({f"word.{k}": v for k, v in WORDS.items()})


def placeholders(template: str) -> set[str]:
    """The parameter names a template uses (``{seconds:.2f}`` → ``seconds``)."""
    return {f for _, f, _, _ in string.Formatter().parse(template) if f}


def _fill(value: Any, lang: str, catalogue: Mapping[str, Mapping[str, str]] | None = None) -> Any:
    """A parameter as it goes into a sentence in ``lang``: a fragment ``{"code", "params"}`` (or a list of them)
    is rendered in ``lang`` from ``catalogue`` when it holds the code, else from this table; a stored message
    (:func:`app.pipeline.service_messages.item`) whose code neither holds keeps its English ``text``."""
    if isinstance(value, Mapping) and "code" in value:
        code = value["code"]
        if catalogue is not None and code in catalogue:
            return render(code, value.get("params", {}), lang, catalogue)
        if code not in CATALOGUE and "text" in value:
            return value["text"]
        return render(code, value.get("params", {}), lang)
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, Mapping) and "code" in v for v in value):
        sep = ", " if all(str(v["code"]).startswith("word.") for v in value) else " "
        return sep.join(_fill(v, lang, catalogue) for v in value)
    if isinstance(value, (list, tuple)) and not value:
        return ""
    return value


#: a code whose parameters were renamed: the new ones from those a stored message (a session's check, a failed
#: job's error; rendered again at every read) still carries.  ``opal.bad_shape`` said ``({n}, 3)`` until its
#: ``{expected}`` also had to say a one-column shape (``/Time``).
STORED_PARAMS: dict[str, Any] = {
    "opal.bad_shape": lambda p: {"expected": f"({p['n']}, 3)"} if "n" in p else {},
}


def render(code: str, params: Mapping[str, Any], lang: str = "en",
           catalogue: Mapping[str, Mapping[str, str]] | None = None) -> str:
    """The message ``code`` in ``lang`` (``es``/``en``/``pt``; others give English), filled from ``params``.

    ``catalogue``: another table of the same shape (the pipeline's, :mod:`app.pipeline.messages`); fragments
    inside the params are looked up there first, then here (:func:`_fill`).  A missing parameter shows as
    ``{name}`` rather than failing: a message must never hide the error."""
    entry = (CATALOGUE if catalogue is None else catalogue)[code]
    template = entry.get(lang) or entry["en"]
    if code in STORED_PARAMS:  # a message stored (checks, job errors) before its parameters were renamed
        params = STORED_PARAMS[code](params) | dict(params)
    values = {k: _fill(v, lang, catalogue) for k, v in params.items()}
    try:
        text = template.format_map(values)
    except (KeyError, ValueError, TypeError, IndexError):
        text = template.format_map(_Lenient(values))
    return " ".join(text.split())  # an empty hint leaves no double space


class _Lenient(dict):
    def __missing__(self, key):
        return "{" + key + "}"

    def __getitem__(self, key):
        value = super().get(key, None)
        return _Raw(value if key in self else "{" + key + "}")


class _Raw:
    """A value that ignores format specs it cannot take (a string where ``:.2f`` was expected)."""

    def __init__(self, value):
        self.value = value

    def __format__(self, spec):
        try:
            return format(self.value, spec)
        except (ValueError, TypeError):
            return str(self.value)


def render_prefix(segment: str, role: str, lang: str = "en") -> str:
    """``"<segment> <role>"`` in ``lang`` (the prefix of a session's notes)."""
    w = lambda x: WORDS.get(x, {}).get(lang, x)  # noqa: E731
    return f"{w(segment)} {w(role)}"


def message_dict(code: str, params: Mapping[str, Any],
                 catalogue: Mapping[str, Mapping[str, str]] | None = None) -> dict[str, Any]:
    """``{"code", "params", "message": {lang: text}}`` for JSON (API answers, job records)."""
    return {"code": code, "params": dict(params),
            "message": {lang: render(code, params, lang, catalogue) for lang in LANGUAGES}}
