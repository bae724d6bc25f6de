/*
 * meshlab_run_filter.cpp - runs MeshLab 2021.05+ filters the way MeshLab does
 *
 * MeshLab 2020.12 dropped meshlabserver and Debian has no PyMeshLab, so the
 * tests of the FilterPlugin adapter drive MeshLab's own library
 * (libmeshlab-common.so of the installed package) from this small program:
 *
 *   - plugins are loaded by MeshLab's PluginManager (the global instance the
 *     GUI uses), so MeshLab's own checks apply: a Qt plugin of a MeshLab
 *     type, the same floating-point precision (MESHLAB_SCALAR) and the same
 *     version (the first six characters of MESHLAB_VERSION) as the running
 *     MeshLab, a valid filter class (PluginManager::checkPlugin);
 *   - a filter is found by its menu text (PluginManager::filterAction), its
 *     parameters come from the plugin's initParameterList() with the given
 *     values set by name and type, and it is applied to a MeshDocument as
 *     MainWindow::executeFilter does (log, data-mask requirements, global
 *     parameters joined, post-condition, compaction);
 *   - --save writes the current layer through the io plugin MeshLab picks for
 *     the extension (here libio_base's PLY), with the vertex normals
 *     (--save-colors: and the vertex colours, meshlabserver's -m vn vc).
 *
 * Usage: meshlab_run_filter [--plugin FILE.so]... [--log FILE] STEP...
 *   STEP:  --filter NAME [--set PARAM=VALUE]...   apply a filter
 *          --save FILE                           save the current layer
 *          --save-colors FILE                    the same with vertex colours
 *          --list NAME                           print a filter's parameters
 * Output on stdout: one JSON object per line, per plugin loaded and per step
 * ({"filter": ..., "ok": true, "outputs": {...}, "layers": N, "vn": ..,
 * "fn": ..} or {"filter": ..., "ok": false, "error": "..."}), the progress
 * callback's stage texts as "progress: N% TEXT" lines; --log FILE gets the
 * document's log, one "LEVEL text" line per entry (as MeshLab's log window).
 * Exit status: 0 every step done; 1 a filter threw MLException (the error is
 * reported, later steps are not run, nothing is saved); 2 usage, a plugin
 * MeshLab refuses, an unknown filter or parameter, a failed save.
 *
 * Runs without a display (QT_QPA_PLATFORM=offscreen is set unless the caller
 * set it): neither the isomend filter nor "Compute Topological Measures"
 * uses OpenGL.
 */
#include <common/globals.h>
#include <common/mlexception.h>
#include <common/ml_document/mesh_document.h>
#include <common/parameters/rich_parameter_list.h>
#include <common/plugins/interfaces/filter_plugin.h>
#include <common/plugins/interfaces/io_plugin.h>
#include <common/plugins/plugin_manager.h>

#include <QApplication>
#include <QFile>
#include <QFileInfo>
#include <QTextStream>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

namespace {

std::string json_string(const QString &text)
{
    const std::string s = text.toStdString();
    std::string out = "\"";
    for (unsigned char c : s) {
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\r': out += "\\r"; break;
        case '\t': out += "\\t"; break;
        default:
            if (c < 0x20) {
                char buf[8];
                std::snprintf(buf, sizeof buf, "\\u%04x", c);
                out += buf;
            } else {
                out += static_cast<char>(c);
            }
        }
    }
    return out + "\"";
}

std::string json_value(const QVariant &v)
{
    switch (static_cast<QMetaType::Type>(v.type())) {
    case QMetaType::Bool: return v.toBool() ? "true" : "false";
    case QMetaType::Int:
    case QMetaType::UInt:
    case QMetaType::Long:
    case QMetaType::LongLong: return std::to_string(v.toLongLong());
    case QMetaType::ULong:
    case QMetaType::ULongLong: return std::to_string(v.toULongLong());
    case QMetaType::Float:
    case QMetaType::Double: {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.17g", v.toDouble());
        return buf;
    }
    default: return json_string(v.toString());
    }
}

void emit_line(const std::string &line)
{
    std::fputs(line.c_str(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
}

bool progress(const int percent, const char *stage)
{
    std::printf("progress: %d%% %s\n", percent, stage ? stage : "");
    std::fflush(stdout);
    return true;
}

struct Step {
    enum Kind { FILTER, SAVE, LIST, SAVE_COLORS } kind;
    QString name;                                    /* filter name or file */
    std::vector<std::pair<QString, QString>> values; /* --set */
};

int usage(const char *message)
{
    std::fprintf(stderr, "meshlab_run_filter: %s\n", message);
    std::fprintf(stderr, "usage: meshlab_run_filter [--plugin FILE.so]... [--log FILE] "
                         "(--filter NAME [--set P=V]... | --save[-colors] FILE | --list NAME)...\n");
    return 2;
}

/* Sets one parameter from its text, by the parameter's own value type. */
bool set_parameter(RichParameterList &par, const QString &name, const QString &text,
                   QString *error)
{
    if (!par.hasParameter(name)) {
        *error = "the filter has no parameter \"" + name + "\"";
        return false;
    }
    RichParameter &p = par.getParameterByName(name);
    const Value &v = p.value();
    bool ok = true;
    if (v.isBool()) {
        if (text == "true" || text == "1")
            p.setValue(BoolValue(true));
        else if (text == "false" || text == "0")
            p.setValue(BoolValue(false));
        else
            ok = false;
    } else if (v.isInt()) { /* RichInt and RichEnum */
        const int i = text.toInt(&ok);
        if (ok)
            p.setValue(IntValue(i));
    } else if (v.isFloat()) {
        const double d = text.toDouble(&ok);
        if (ok)
            p.setValue(FloatValue(static_cast<Scalarm>(d)));
    } else if (v.isString()) {
        p.setValue(StringValue(text));
    } else {
        *error = "parameter \"" + name + "\" is of a type this harness cannot set (" +
                 p.stringType() + ")";
        return false;
    }
    if (!ok)
        *error = "\"" + text + "\" is not a value for parameter \"" + name + "\" (" +
                 p.stringType() + ")";
    return ok;
}

class Runner {
public:
    explicit Runner(PluginManager &pm) : pm_(pm) {}

    /* 0 done, 1 the filter failed, 2 harness error */
    int filter(const Step &step)
    {
        QAction *action = nullptr;
        FilterPlugin *plugin = find(step, "filter", &action);
        if (!plugin)
            return 2;
        plugin->setLog(&md_.Log);
        RichParameterList par = plugin->initParameterList(action, md_);
        for (const auto &nv : step.values) {
            QString error;
            if (!set_parameter(par, nv.first, nv.second, &error)) {
                emit_line("{\"filter\": " + json_string(step.name) +
                          ", \"ok\": false, \"error\": " + json_string(error) + "}");
                return 2;
            }
        }
        const int req = plugin->getRequirements(action);
        if (md_.meshNumber() != 0)
            md_.mm()->updateDataMask(req);
        RichParameterList merged(par);
        merged.join(meshlab::defaultGlobalParameterList());
        std::map<std::string, QVariant> outputs;
        try {
            md_.meshDocStateData().clear();
            md_.meshDocStateData().create(md_);
            unsigned int post = MeshModel::MM_UNKNOWN;
            outputs = plugin->applyFilter(action, merged, md_, post, progress);
            if (post == MeshModel::MM_UNKNOWN)
                post = plugin->postCondition(action);
            for (MeshModel &m : md_.meshIterator())
                vcg::tri::Allocator<CMeshO>::CompactEveryVector(m.cm);
            md_.meshDocStateData().clear();
        } catch (const MLException &e) {
            md_.meshDocStateData().clear();
            emit_line("{\"filter\": " + json_string(step.name) + ", \"ok\": false, \"error\": " +
                      json_string(QString::fromUtf8(e.what())) +
                      ", \"layers\": " + std::to_string(md_.meshNumber()) + "}");
            return 1;
        }
        md_.Log.logf(GLLogStream::SYSTEM, "Applied filter %s", qUtf8Printable(step.name));
        std::string line = "{\"filter\": " + json_string(step.name) + ", \"ok\": true";
        line += ", \"layers\": " + std::to_string(md_.meshNumber());
        if (md_.mm()) {
            line += ", \"layer\": " + json_string(md_.mm()->label());
            line += ", \"vn\": " + std::to_string(md_.mm()->cm.vn);
            line += ", \"fn\": " + std::to_string(md_.mm()->cm.fn);
        }
        line += ", \"outputs\": {";
        bool first = true;
        for (const auto &kv : outputs) {
            line += (first ? "" : ", ") + json_string(QString::fromStdString(kv.first)) + ": " +
                    json_value(kv.second);
            first = false;
        }
        emit_line(line + "}}");
        return 0;
    }

    /* The current layer, positions and vertex normals (meshlabserver's -m vn). */
    int save(const Step &step)
    {
        const QString extension = QFileInfo(step.name).suffix().toLower();
        IOPlugin *io = pm_.outputMeshPlugin(extension);
        if (!md_.mm() || !io) {
            emit_line("{\"saved\": " + json_string(step.name) + ", \"ok\": false, \"error\": " +
                      json_string(!md_.mm() ? "no layer" : "no io plugin for " + extension) + "}");
            return 2;
        }
        try {
            io->setLog(&md_.Log);
            int capability = 0, defaults = 0;
            io->exportMaskCapability(extension, capability, defaults);
            const int mask =
                capability & (vcg::tri::io::Mask::IOM_VERTNORMAL |
                              (step.kind == Step::SAVE_COLORS ? vcg::tri::io::Mask::IOM_VERTCOLOR : 0));
            RichParameterList save_par = io->initSaveParameter(extension, *md_.mm());
            io->save(extension, step.name, *md_.mm(), mask, save_par, nullptr);
        } catch (const MLException &e) {
            emit_line("{\"saved\": " + json_string(step.name) + ", \"ok\": false, \"error\": " +
                      json_string(QString::fromUtf8(e.what())) + "}");
            return 2;
        }
        emit_line("{\"saved\": " + json_string(step.name) + ", \"ok\": true, \"plugin\": " +
                  json_string(io->pluginName()) + "}");
        return 0;
    }

    int list(const Step &step)
    {
        QAction *action = nullptr;
        FilterPlugin *plugin = find(step, "list", &action);
        if (!plugin)
            return 2;
        std::string line = "{\"list\": " + json_string(step.name) + ", \"ok\": true";
        line += ", \"plugin\": " + json_string(plugin->pluginName());
        line += ", \"python_name\": " + json_string(plugin->pythonFilterName(action));
        line += ", \"class\": " + std::to_string(static_cast<int>(plugin->getClass(action)));
        line += ", \"info\": " + json_string(plugin->filterInfo(action));
        line += ", \"parameters\": [";
        bool first = true;
        for (const RichParameter &p : plugin->initParameterList(action, md_)) {
            line += std::string(first ? "" : ", ") + "{\"name\": " + json_string(p.name()) +
                    ", \"type\": " + json_string(p.stringType()) +
                    ", \"label\": " + json_string(p.fieldDescription()) +
                    ", \"tooltip\": " + json_string(p.toolTip()) + "}";
            first = false;
        }
        emit_line(line + "]}");
        return 0;
    }

    void write_log(const QString &path) const
    {
        QFile f(path);
        if (!f.open(QIODevice::WriteOnly | QIODevice::Truncate | QIODevice::Text))
            return;
        QTextStream out(&f);
        for (const auto &entry : md_.Log.logStringList())
            out << entry.first << " " << entry.second << "\n";
    }

private:
    /* The filter named by the step, by its menu text; reported when absent. */
    FilterPlugin *find(const Step &step, const char *key, QAction **action)
    {
        *action = pm_.filterAction(step.name);
        FilterPlugin *plugin = *action ? pm_.getFilterPluginFromAction(*action) : nullptr;
        if (!plugin)
            emit_line(std::string("{\"") + key + "\": " + json_string(step.name) +
                      ", \"ok\": false, \"error\": \"no loaded plugin has this filter\"}");
        return plugin;
    }

    PluginManager &pm_;
    MeshDocument md_;
};

} // namespace

int main(int argc, char **argv)
{
    if (!std::getenv("QT_QPA_PLATFORM"))
        setenv("QT_QPA_PLATFORM", "offscreen", 1);
    /* Qt would take "--plugin" as its own option: it gets argv[0] only. */
    int qt_argc = 1;
    QApplication app(qt_argc, argv);

    std::vector<QString> plugins;
    std::vector<Step> steps;
    QString log_path;
    QStringList args;
    for (int i = 0; i < argc; ++i)
        args << QString::fromLocal8Bit(argv[i]);
    for (int i = 1; i < args.size(); ++i) {
        const QString &a = args[i];
        const bool has_value = i + 1 < args.size();
        if (a == "--plugin" && has_value) {
            plugins.push_back(args[++i]);
        } else if (a == "--log" && has_value) {
            log_path = args[++i];
        } else if (a == "--filter" && has_value) {
            steps.push_back({Step::FILTER, args[++i], {}});
        } else if (a == "--save" && has_value) {
            steps.push_back({Step::SAVE, args[++i], {}});
        } else if (a == "--save-colors" && has_value) {
            steps.push_back({Step::SAVE_COLORS, args[++i], {}});
        } else if (a == "--list" && has_value) {
            steps.push_back({Step::LIST, args[++i], {}});
        } else if (a == "--set" && has_value) {
            const QString nv = args[++i];
            const int eq = nv.indexOf('=');
            if (steps.empty() || steps.back().kind != Step::FILTER || eq <= 0)
                return usage("--set NAME=VALUE must follow --filter");
            steps.back().values.emplace_back(nv.left(eq), nv.mid(eq + 1));
        } else {
            return usage(("unknown or incomplete argument " + a).toUtf8().constData());
        }
    }
    if (steps.empty())
        return usage("nothing to do");

    PluginManager &pm = meshlab::pluginManagerInstance();
    for (const QString &file : plugins) {
        try {
            MeshLabPlugin *p = pm.loadPlugin(file);
            emit_line("{\"plugin\": " + json_string(file) + ", \"loaded\": true, \"name\": " +
                      json_string(p->pluginName()) + "}");
        } catch (const MLException &e) {
            emit_line("{\"plugin\": " + json_string(file) + ", \"loaded\": false, \"error\": " +
                      json_string(QString::fromUtf8(e.what())) + "}");
            return 2;
        }
    }

    Runner run(pm);
    int rc = 0;
    for (const Step &step : steps) {
        rc = step.kind == Step::FILTER ? run.filter(step)
             : step.kind == Step::LIST ? run.list(step)
                                       : run.save(step);
        if (rc != 0)
            break;
    }
    if (!log_path.isEmpty())
        run.write_log(log_path);
    return rc;
}
